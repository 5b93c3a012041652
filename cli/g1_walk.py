"""CLI: ``mbctl g1-walk SCENARIO`` — the G1 walks on the whole-body QP, after a velocity command."""

from __future__ import annotations

from typing import Annotated, Any

import typer

from mbctl.cli._run import OutputOpt, QuietOpt, VideoOpt, VideoSizeOpt, execute, video_spec
from mbctl.cli.plant_options import MODEL_PARAMETERS, PLANT_PARAMETERS, with_options
from mbctl.cli.robots import ModelDirOpt, ModelErrorOpt
from mbctl.jobs.g1_walk_choices import (
    WALK_DEFAULT_DURATION_S,
    WALK_DEFAULT_SPEED,
    WALK_GAITS,
    WALK_PUSH_PHASES,
    WALK_SCENARIOS,
)


@with_options(PLANT_PARAMETERS, MODEL_PARAMETERS)
def g1_walk(
    scenario: Annotated[str, typer.Argument(help=f"One of: {', '.join(WALK_SCENARIOS)}.")] = "forward",
    speed: Annotated[
        str | None,
        typer.Option("--speed", help="The command VX[,VY[,YAW_RATE]] (m/s, m/s, rad/s) in the body frame; "
                                     "backward takes VX as a backward speed (default per scenario: "
                                     + ", ".join(f"{k} {','.join(f'{v:g}' for v in s)}"
                                                 for k, s in WALK_DEFAULT_SPEED.items()) + ")."),
    ] = None,
    duration: Annotated[
        float | None,
        typer.Option("--duration", help="Simulated time (s) (default per scenario: " + ", ".join(
            f"{k} {v:g}" for k, v in WALK_DEFAULT_DURATION_S.items()) + ")."),
    ] = None,
    impulse: Annotated[
        float | None,
        typer.Option("--impulse", help="Push impulse (N s): a force on the pelvis held --push-hold (push "
                                       "only; default 15)."),
    ] = None,
    direction: Annotated[
        float | None,
        typer.Option("--direction", help="Push direction (deg): 0 = +x (the start heading), 90 = +y (its "
                                         "left); default: 8 directions 45 deg apart, 3 s apart (push only)."),
    ] = None,
    push_phase: Annotated[
        str | None,
        typer.Option("--push-phase", help=f"The gait phase a push starts in: {', '.join(WALK_PUSH_PHASES)} "
                                          "(10 % or 60 % of the swing, or double support; push only; default "
                                          "early)."),
    ] = None,
    push_hold: Annotated[
        float | None,
        typer.Option("--push-hold", help="How long a push's force is held (s, > 0; the force is impulse / "
                                         "hold; push only; default 0.1)."),
    ] = None,
    waypoints: Annotated[
        str | None,
        typer.Option("--waypoints", help="The course: X,Y,YAW;X,Y,YAW;... (m, m, deg; the start is the "
                                         "origin, heading +x) or a file of such lines (course only; default: "
                                         "12 waypoints over about 10 m); --speed caps the command."),
    ] = None,
    gait: Annotated[
        str,
        typer.Option("--gait", help=f"The walking options: {', '.join(WALK_GAITS)} (quick, the default: a "
                                    "step every 0.31 s, a lighter torso turned against the legs, up to ~1 "
                                    "m/s; normal: a step every 0.6 s, capped near 0.6 m/s)."),
    ] = "quick",
    model_error: ModelErrorOpt = 0.0,
    model_dir: ModelDirOpt = None,
    output: OutputOpt = None,
    quiet: QuietOpt = False,
    video: VideoOpt = False,
    video_size: VideoSizeOpt = "640x480",
    extra: dict[str, Any] | None = None,
) -> None:
    """Walk the G1 in torque mode (footsteps, DCM, swing feet on the whole-body QP); exit 1 if it fell.

    Exit 1 too below 90 % of the commanded displacement (the turn for `turn`; for `course`, a
    waypoint missed; for `push`, a push not survived), or walking forward above a 5 mm median foot
    slip. --interface dds runs the same controller over the G1's low-level DDS (`mbctl serve g1
    --start crouched`).
    """
    from mbctl.jobs.g1_walk import G1_WALK, g1_walk_params

    params = g1_walk_params(scenario=scenario, speed=speed, duration=duration, impulse=impulse,
                            direction=direction, push_phase=push_phase, push_hold=push_hold,
                            waypoints=waypoints, gait=gait,
                            model_error=model_error,
                            model_dir=model_dir, **(extra or {}))
    execute(G1_WALK, params, output, quiet, video_spec(video, video_size))


def register(app: typer.Typer) -> None:
    """Add this module's commands to ``app``."""
    app.command("g1-walk")(g1_walk)
