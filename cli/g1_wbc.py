"""CLI: ``mbctl g1-wbc SCENARIO`` — whole-body inverse dynamics on the floating-base G1."""

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
from mbctl.jobs.choices import WBC_DEFAULT_DURATION_S, WBC_SCENARIOS


def g1_wbc(
    scenario: Annotated[str, typer.Argument(help=f"One of: {', '.join(WBC_SCENARIOS)}.")] = "stand",
    duration: Annotated[
        float | None,
        typer.Option("--duration", help="Simulated time (s) (default per scenario: " + ", ".join(
            f"{k} {v:g}" for k, v in WBC_DEFAULT_DURATION_S.items()) + ")."),
    ] = None,
    impulse: Annotated[
        float | None,
        typer.Option("--impulse", help="Push impulse (N s): force held 0.1 s (push scenario only; "
                                       "default 10)."),
    ] = None,
    direction: Annotated[
        float | None,
        typer.Option("--direction", help="Push direction (deg): 0 = +x (front), 90 = +y (left); "
                                         "default: 8 directions 45 deg apart (push scenario only)."),
    ] = None,
    model_error: Annotated[
        float, typer.Option("--model-error", help="Controller model link masses off by PCT (%).")
    ] = 0.0,
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
    """Whole-body inverse dynamics (QP) on the G1 in torque mode; exit 1 if it fell or missed a bound.

    --interface dds runs the same controller on the G1's low-level DDS (a robot, or `mbctl serve g1
    --start crouched`); the push scenario is in-process only.
    """
    from mbctl.jobs import options
    from mbctl.jobs.g1_wbc import G1_WBC

    params = options.g1_wbc(scenario=scenario, duration=duration, impulse=impulse, direction=direction,
                            model_error=model_error, model_dir=model_dir, interface=interface, domain=domain,
                            network_interface=network_interface, latency_ms=latency_ms, jitter_ms=jitter_ms,
                            drop=drop, imu_noise=imu_noise, estimate=estimate, link_seed=link_seed,
                            truth=truth, watchdog_periods=watchdog_periods, dry_run=dry_run,
                              payload=payload, plant_error=plant_error, controller_model=controller_model)
    execute(G1_WBC, params, output, quiet, video_spec(video, video_size))


def register(app: typer.Typer) -> None:
    """Add this module's commands to ``app``."""
    app.command("g1-wbc")(g1_wbc)
