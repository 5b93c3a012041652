"""CLI: ``mbctl demo`` — the 2-link torque arm draws a Cartesian square under computed torque."""

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
from mbctl.cli.plant_options import MODEL_PARAMETERS, with_options
from mbctl.cli.robots import ModelErrorOpt
from mbctl.jobs.choices import CONTROLLERS


@with_options(MODEL_PARAMETERS)
def demo(
    controller: Annotated[str, typer.Option(help=f"One of: {', '.join(CONTROLLERS)}.")] = "ct",
    compare: Annotated[
        bool, typer.Option("--compare", help="Run every controller on the same reference.")
    ] = False,
    model_error: ModelErrorOpt = 0.0,
    duration: Annotated[
        float | None, typer.Option(help="Run length (s) (default: the whole square, ~2.8 s).")
    ] = None,
    side: Annotated[float, typer.Option(help="Square side length (m).")] = 0.2,
    speed: Annotated[float, typer.Option(help="Path speed limit (m/s).")] = 0.5,
    omega: Annotated[float, typer.Option(help="Closed-loop natural frequency (rad/s).")] = 30.0,
    gravity: Annotated[
        bool, typer.Option("--gravity/--no-gravity", help="In-plane gravity (-y) on or off.")
    ] = True,
    max_rms_mm: Annotated[
        float | None, typer.Option("--max-rms-mm", help="Exit 1 above this Cartesian RMS error (mm).")
    ] = None,
    output: OutputOpt = None,
    quiet: QuietOpt = False,
    video: VideoOpt = False,
    video_size: VideoSizeOpt = "640x480",
    extra: dict[str, Any] | None = None,
) -> None:
    """Track a Cartesian square on the 2-link torque arm; print RMS and max Cartesian error."""
    from mbctl.jobs import options
    from mbctl.jobs.demo import DEMO

    config = options.demo(controller=controller, compare=compare, model_error=model_error, duration=duration,
                          side=side, speed=speed, omega=omega, gravity=gravity, max_rms_mm=max_rms_mm,
                          **(extra or {}))
    execute(DEMO, config, output, quiet, video_spec(video, video_size))


def register(app: typer.Typer) -> None:
    """Add this module's commands to ``app``."""
    app.command("demo")(demo)
