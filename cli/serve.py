"""CLI: ``mbctl serve g1`` — the MuJoCo G1 on DDS, speaking the robot's low-level messages."""

from __future__ import annotations

from typing import Annotated

import typer

from mbctl.cli._run import OutputOpt, QuietOpt, execute
from mbctl.cli.plant_options import (
    DomainOpt,
    DropOpt,
    ImuNoiseOpt,
    JitterOpt,
    LatencyOpt,
    NetworkOpt,
    SeedOpt,
)
from mbctl.cli.robots import ModelDirOpt
from mbctl.jobs.choices import SERVE_STARTS


def serve(
    robot: Annotated[str, typer.Argument(help="The robot to serve (g1).")] = "g1",
    start: Annotated[str, typer.Option("--start", help=f"Initial pose: {' or '.join(SERVE_STARTS)} "
                                                       "(g1-wbc starts crouched).")] = "stand",
    domain: DomainOpt = 0,
    network_interface: NetworkOpt = "lo",
    latency_ms: LatencyOpt = 0.0,
    jitter_ms: JitterOpt = 0.0,
    drop: DropOpt = 0.0,
    imu_noise: ImuNoiseOpt = 0.0,
    seed: SeedOpt = 0,
    duration: Annotated[
        float | None, typer.Option("--duration", help="Stop after this wall time (s).")] = None,
    idle_timeout: Annotated[
        float | None, typer.Option("--idle-timeout", help="Stop once no command came for this long (s), "
                                                          "counted from the start until the first.")] = None,
    lockstep: Annotated[bool, typer.Option("--lockstep", help="Advance the physics one period per command "
                                                              "received (no faster than real time): the same "
                                                              "result on a loaded machine.")] = False,
    model_dir: ModelDirOpt = None,
    output: OutputOpt = None,
    quiet: QuietOpt = False,
) -> None:
    """Run the MuJoCo G1 as the robot on DDS (rt/lowcmd in, rt/lowstate out); truth.csv in the run folder.

    The physics waits for the first valid command. Ctrl-C stops it (exit 130, every row kept); a plant
    that diverges stops it (exit 1).
    """
    from mbctl.jobs import options
    from mbctl.jobs.serve import SERVE

    params = options.serve(robot=robot, start=start, domain=domain, network_interface=network_interface,
                           latency_ms=latency_ms, jitter_ms=jitter_ms, drop=drop, imu_noise=imu_noise,
                           seed=seed, duration=duration, idle_timeout=idle_timeout, model_dir=model_dir,
                           lockstep=lockstep)
    execute(SERVE, params, output, quiet)


def register(app: typer.Typer) -> None:
    """Add this module's commands to ``app``."""
    app.command("serve")(serve)
