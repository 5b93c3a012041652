"""CLI: ``mbctl g1-stand``, ``mbctl g1-track``, ``mbctl g1-arm-pd`` — control jobs on the G1."""

from __future__ import annotations

from typing import Annotated

import typer

from mbctl.cli._run import (
    ControllerModelOpt,
    OutputOpt,
    PayloadOpt,
    PlantErrorOpt,
    QuietOpt,
    VideoOpt,
    VideoSizeOpt,
    execute,
    video_spec,
)
from mbctl.cli.plant_options import (
    DomainOpt,
    DropOpt,
    DryRunOpt,
    EstimateOpt,
    ImuNoiseOpt,
    InterfaceOpt,
    JitterOpt,
    LatencyOpt,
    LinkSeedOpt,
    NetworkOpt,
    TruthOpt,
    WatchdogOpt,
)
from mbctl.cli.robots import ModelDirOpt

Omega = Annotated[float, typer.Option("--omega", help="Closed-loop natural frequency (rad/s).")]
Zeta = Annotated[float, typer.Option("--zeta", help="Damping ratio (-).")]
MaxRms = Annotated[
    float | None, typer.Option("--max-rms-rad", help="Exit 1 above this joint RMS error (rad).")
]
TrajectoryDuration = Annotated[
    float | None, typer.Option("--duration", help="Simulated time (s) (default: the whole trajectory).")
]


def stand(
    duration: Annotated[float, typer.Option("--duration", help="Simulated time (s).")] = 10.0,
    omega: Omega = 10.0,
    zeta: Zeta = 1.0,
    model_dir: ModelDirOpt = None,
    interface: InterfaceOpt = "sim",
    domain: DomainOpt = 0,
    network_interface: NetworkOpt = "lo",
    latency_ms: LatencyOpt = 0.0,
    jitter_ms: JitterOpt = 0.0,
    drop: DropOpt = 0.0,
    imu_noise: ImuNoiseOpt = 0.0,
    estimate: EstimateOpt = False,
    link_seed: LinkSeedOpt = 0,
    truth: TruthOpt = None,
    watchdog_periods: WatchdogOpt = 3,
    dry_run: DryRunOpt = False,
    payload: PayloadOpt = None,
    plant_error: PlantErrorOpt = 0.0,
    controller_model: ControllerModelOpt = None,
    output: OutputOpt = None,
    quiet: QuietOpt = False,
    video: VideoOpt = False,
    video_size: VideoSizeOpt = "640x480",
) -> None:
    """Stand on the floor under PD + gravity compensation in torque mode; exit 1 if it fell.

    --interface dds runs the same controller on the G1's low-level DDS (a robot, or `mbctl serve g1`).
    """
    from mbctl.jobs import options
    from mbctl.jobs.g1 import G1_STAND

    params = options.g1_stand(duration=duration, omega=omega, zeta=zeta, model_dir=model_dir,
                              interface=interface, domain=domain, network_interface=network_interface,
                              latency_ms=latency_ms, jitter_ms=jitter_ms, drop=drop, imu_noise=imu_noise,
                              estimate=estimate, link_seed=link_seed, truth=truth,
                              watchdog_periods=watchdog_periods, dry_run=dry_run,
                              payload=payload, plant_error=plant_error, controller_model=controller_model)
    execute(G1_STAND, params, output, quiet, video_spec(video, video_size))


def track(
    duration: TrajectoryDuration = None,
    omega: Omega = 40.0,
    zeta: Zeta = 1.0,
    max_rms_rad: MaxRms = None,
    model_dir: ModelDirOpt = None,
    payload: PayloadOpt = None,
    plant_error: PlantErrorOpt = 0.0,
    controller_model: ControllerModelOpt = None,
    output: OutputOpt = None,
    quiet: QuietOpt = False,
    video: VideoOpt = False,
    video_size: VideoSizeOpt = "640x480",
) -> None:
    """Computed torque on the welded-base G1 along ruckig trajectories (arms, legs, waist).

    In-process only: the welded base is a simulation edit no real robot has.
    """
    from mbctl.jobs import options
    from mbctl.jobs.g1 import G1_TRACK

    params = options.g1_track(duration=duration, omega=omega, zeta=zeta, max_rms_rad=max_rms_rad,
                              model_dir=model_dir, payload=payload, plant_error=plant_error,
                              controller_model=controller_model)
    execute(G1_TRACK, params, output, quiet, video_spec(video, video_size))


def arm_pd(
    duration: TrajectoryDuration = None,
    side: Annotated[str, typer.Option("--side", help="left or right arm.")] = "left",
    gravity_feedforward: Annotated[
        bool,
        typer.Option("--gravity-feedforward/--no-gravity-feedforward", help="Offset targets by g(q)/kp."),
    ] = True,
    max_rms_rad: MaxRms = None,
    model_dir: ModelDirOpt = None,
    interface: InterfaceOpt = "sim",
    domain: DomainOpt = 0,
    network_interface: NetworkOpt = "lo",
    latency_ms: LatencyOpt = 0.0,
    jitter_ms: JitterOpt = 0.0,
    drop: DropOpt = 0.0,
    imu_noise: ImuNoiseOpt = 0.0,
    estimate: EstimateOpt = False,
    link_seed: LinkSeedOpt = 0,
    truth: TruthOpt = None,
    watchdog_periods: WatchdogOpt = 3,
    dry_run: DryRunOpt = False,
    payload: PayloadOpt = None,
    plant_error: PlantErrorOpt = 0.0,
    controller_model: ControllerModelOpt = None,
    output: OutputOpt = None,
    quiet: QuietOpt = False,
    video: VideoOpt = False,
    video_size: VideoSizeOpt = "640x480",
) -> None:
    """One arm follows a ruckig trajectory through the Menagerie position actuators.

    Over DDS (--interface dds) the targets go out as position commands with the actuators' kp and kv.
    """
    from mbctl.jobs import options
    from mbctl.jobs.g1 import G1_ARM_PD

    params = options.g1_arm_pd(duration=duration, side=side, gravity_feedforward=gravity_feedforward,
                               max_rms_rad=max_rms_rad, model_dir=model_dir, interface=interface,
                               domain=domain,
                               network_interface=network_interface, latency_ms=latency_ms,
                               jitter_ms=jitter_ms, drop=drop, imu_noise=imu_noise, estimate=estimate,
                               link_seed=link_seed, truth=truth, watchdog_periods=watchdog_periods,
                               dry_run=dry_run, payload=payload, plant_error=plant_error,
                               controller_model=controller_model)
    execute(G1_ARM_PD, params, output, quiet, video_spec(video, video_size))


def register(app: typer.Typer) -> None:
    """Add this module's commands to ``app``."""
    app.command("g1-stand")(stand)
    app.command("g1-track")(track)
    app.command("g1-arm-pd")(arm_pd)
