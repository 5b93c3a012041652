"""CLI: ``mbctl excite`` and ``mbctl identify`` — record an exciting motion, identify the robot from it."""

from __future__ import annotations

from typing import Annotated, Any

import typer

from mbctl.cli._run import (
    OutputOpt,
    QuietOpt,
    VideoOpt,
    VideoSizeOpt,
    execute,
    video_spec,
)
from mbctl.cli.plant_options import MODEL_PARAMETERS, PLANT_PARAMETERS, with_options
from mbctl.cli.robots import ModelDirOpt, RobotArg, SceneOpt


@with_options(PLANT_PARAMETERS, MODEL_PARAMETERS)
def excite(
    robot: RobotArg,
    duration: Annotated[
        float | None,
        typer.Option(help="Simulated time (s) (default: 30)."),
    ] = None,
    seed: Annotated[int, typer.Option(help="Seed of the excitation design's random start.")] = 0,
    period: Annotated[float, typer.Option(help="Period of the Fourier series' fundamental (s).")] = 5.0,
    harmonics: Annotated[int, typer.Option(help="Harmonics per joint.")] = 5,
    gravity: Annotated[
        bool,
        typer.Option("--gravity/--no-gravity", help="Switch on the robot's gravity (2-link: in its plane)."),
    ] = True,
    scene: SceneOpt = None,
    model_dir: ModelDirOpt = None,
    output: OutputOpt = None,
    quiet: QuietOpt = False,
    video: VideoOpt = False,
    video_size: VideoSizeOpt = "640x480",
    extra: dict[str, Any] | None = None,
) -> None:
    """Drive the plant through an optimised excitation and record the identification log.

    The G1 runs in-process or, with --interface dds, on its low-level DDS (a robot, or `mbctl serve
    g1 --start crouched`) with the safety of the G1 jobs; its balance watch scales the motion down,
    or stops it into a stance, before it falls.
    """
    from mbctl.jobs import options
    from mbctl.jobs.excite import EXCITE

    params = options.excite(robot=robot, duration=duration, seed=seed, period=period, harmonics=harmonics,
                            gravity=gravity, scene=scene, model_dir=model_dir, **(extra or {}))
    execute(EXCITE, params, output, quiet, video_spec(video, video_size))


def identify(
    runs: Annotated[list[str], typer.Argument(help="Run folders of mbctl excite (one or more).")],
    robot: Annotated[
        str | None, typer.Option(help="Nominal robot (name or MJCF) (default: the one the logs name).")
    ] = None,
    bodies: Annotated[
        str | None, typer.Option(help="Bodies to identify, comma-separated (default: every body that moves).")
    ] = None,
    friction: Annotated[
        bool, typer.Option("--friction", help="Identify viscous and Coulomb friction.")
    ] = False,
    armature: Annotated[bool, typer.Option("--armature", help="Identify rotor armature per joint.")] = False,
    contact: Annotated[
        str, typer.Option(help="Contacts: projected (joint torques only) or measured (the logged wrenches).")
    ] = "projected",
    cutoff_hz: Annotated[float, typer.Option("--cutoff-hz", help="Low-pass cutoff (Hz); 0: none.")] = 10.0,
    rate_hz: Annotated[
        float, typer.Option("--rate-hz", help="Decimation rate (Hz); 0: every sample.")
    ] = 100.0,
    validation: Annotated[
        float, typer.Option(help="Last fraction of each log kept for validation (-).")
    ] = 0.25,
    torque_noise: Annotated[
        float,
        typer.Option("--torque-noise", help="Study: add torque noise, PCT of each joint's RMS torque (%)."),
    ] = 0.0,
    encoder_noise: Annotated[
        float,
        typer.Option("--encoder-noise", help="Study: add encoder noise (rad), and its difference on v."),
    ] = 0.0,
    seed: Annotated[int, typer.Option(help="Seed of the added noise and of the structural states.")] = 0,
    allow_other_model: Annotated[
        bool,
        typer.Option("--allow-other-model", help="Identify from logs recorded on another model than the "
                     "nominal one (another dynamics fingerprint, or none); refused otherwise (exit 2). "
                     "Recorded in identify_report.json."),
    ] = False,
    model_dir: ModelDirOpt = None,
    output: OutputOpt = None,
    quiet: QuietOpt = False,
) -> None:
    """Identify the robot's inertial parameters (and friction, armature) from excitation logs."""
    from dataclasses import replace

    from mbctl.jobs import options
    from mbctl.jobs.identify import IDENTIFY

    params = options.identify(runs=runs, robot=robot, bodies=bodies, friction=friction, armature=armature,
                              contact=contact, cutoff_hz=cutoff_hz, rate_hz=rate_hz, validation=validation,
                              torque_noise=torque_noise, encoder_noise=encoder_noise, seed=seed,
                              model_dir=model_dir)
    params = replace(params, allow_other_model=allow_other_model)
    execute(IDENTIFY, params, output, quiet)  # run_job defaults to out/identify


def register(app: typer.Typer) -> None:
    """Add this module's commands to ``app``."""
    app.command("excite")(excite)
    app.command("identify")(identify)
