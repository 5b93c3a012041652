"""CLI: ``mbctl g1-stand``, ``mbctl g1-track``, ``mbctl g1-arm-pd`` — control jobs on the G1."""

from __future__ import annotations

from typing import Annotated, Any

import typer

from mbctl.cli._run import OutputOpt, QuietOpt, VideoOpt, VideoSizeOpt, execute, video_spec
from mbctl.cli.plant_options import MODEL_PARAMETERS, PLANT_PARAMETERS, with_options
from mbctl.cli.robots import ModelDirOpt

Omega = Annotated[float, typer.Option("--omega", help="Closed-loop natural frequency (rad/s).")]
Zeta = Annotated[float, typer.Option("--zeta", help="Damping ratio (-).")]
MaxRms = Annotated[
    float | None, typer.Option("--max-rms-rad", help="Exit 1 above this joint RMS error (rad).")
]
TrajectoryDuration = Annotated[
    float | None, typer.Option("--duration", help="Simulated time (s) (default: the whole trajectory).")
]


@with_options(PLANT_PARAMETERS, MODEL_PARAMETERS)
def stand(
    duration: Annotated[float, typer.Option("--duration", help="Simulated time (s).")] = 10.0,
    omega: Omega = 10.0,
    zeta: Zeta = 1.0,
    model_dir: ModelDirOpt = None,
    output: OutputOpt = None,
    quiet: QuietOpt = False,
    video: VideoOpt = False,
    video_size: VideoSizeOpt = "640x480",
    extra: dict[str, Any] | None = None,
) -> None:
    """Stand on the floor under PD + gravity compensation in torque mode; exit 1 if it fell.

    --interface dds runs the same controller on the G1's low-level DDS (a robot, or `mbctl serve g1`).
    """
    from mbctl.jobs import options
    from mbctl.jobs.g1 import G1_STAND

    params = options.g1_stand(duration=duration, omega=omega, zeta=zeta, model_dir=model_dir, **(extra or {}))
    execute(G1_STAND, params, output, quiet, video_spec(video, video_size))


@with_options(MODEL_PARAMETERS)
def track(
    duration: TrajectoryDuration = None,
    omega: Omega = 40.0,
    zeta: Zeta = 1.0,
    max_rms_rad: MaxRms = None,
    model_dir: ModelDirOpt = None,
    output: OutputOpt = None,
    quiet: QuietOpt = False,
    video: VideoOpt = False,
    video_size: VideoSizeOpt = "640x480",
    extra: dict[str, Any] | None = None,
) -> None:
    """Computed torque on the welded-base G1 along ruckig trajectories (arms, legs, waist).

    In-process only: the welded base is a simulation edit no real robot has.
    """
    from mbctl.jobs import options
    from mbctl.jobs.g1 import G1_TRACK

    params = options.g1_track(duration=duration, omega=omega, zeta=zeta, max_rms_rad=max_rms_rad,
                              model_dir=model_dir, **(extra or {}))
    execute(G1_TRACK, params, output, quiet, video_spec(video, video_size))


@with_options(PLANT_PARAMETERS, MODEL_PARAMETERS)
def arm_pd(
    duration: TrajectoryDuration = None,
    side: Annotated[str, typer.Option("--side", help="left or right arm.")] = "left",
    gravity_feedforward: Annotated[
        bool,
        typer.Option("--gravity-feedforward/--no-gravity-feedforward", help="Offset targets by g(q)/kp."),
    ] = True,
    max_rms_rad: MaxRms = None,
    model_dir: ModelDirOpt = None,
    output: OutputOpt = None,
    quiet: QuietOpt = False,
    video: VideoOpt = False,
    video_size: VideoSizeOpt = "640x480",
    extra: dict[str, Any] | None = None,
) -> None:
    """One arm follows a ruckig trajectory through the Menagerie position actuators.

    Over DDS (--interface dds) the targets go out as position commands with the actuators' kp and kv.
    """
    from mbctl.jobs import options
    from mbctl.jobs.g1 import G1_ARM_PD

    params = options.g1_arm_pd(duration=duration, side=side, gravity_feedforward=gravity_feedforward,
                               max_rms_rad=max_rms_rad, model_dir=model_dir, **(extra or {}))
    execute(G1_ARM_PD, params, output, quiet, video_spec(video, video_size))


def register(app: typer.Typer) -> None:
    """Add this module's commands to ``app``."""
    app.command("g1-stand")(stand)
    app.command("g1-track")(track)
    app.command("g1-arm-pd")(arm_pd)
