"""CLI: ``mbctl g1-wbc SCENARIO`` — whole-body inverse dynamics on the floating-base G1."""

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
from mbctl.cli.robots import ModelDirOpt, ModelErrorOpt
from mbctl.jobs.choices import WBC_DEFAULT_DURATION_S, WBC_SCENARIOS


@with_options(PLANT_PARAMETERS, MODEL_PARAMETERS)
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
    model_error: ModelErrorOpt = 0.0,
    model_dir: ModelDirOpt = None,
    output: OutputOpt = None,
    quiet: QuietOpt = False,
    video: VideoOpt = False,
    video_size: VideoSizeOpt = "640x480",
    extra: dict[str, Any] | None = None,
) -> None:
    """Whole-body inverse dynamics (QP) on the G1 in torque mode; exit 1 if it fell or missed a bound.

    --interface dds runs the same controller on the G1's low-level DDS (a robot, or `mbctl serve g1
    --start crouched`); the push scenario is in-process only.
    """
    from mbctl.jobs import options
    from mbctl.jobs.g1_wbc import G1_WBC

    params = options.g1_wbc(scenario=scenario, duration=duration, impulse=impulse, direction=direction,
                            model_error=model_error, model_dir=model_dir, **(extra or {}))
    execute(G1_WBC, params, output, quiet, video_spec(video, video_size))


def register(app: typer.Typer) -> None:
    """Add this module's commands to ``app``."""
    app.command("g1-wbc")(g1_wbc)
