"""CLI: ``mbctl verify`` and ``mbctl joint-step`` — the plant's setup checks and a joint step."""

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
from mbctl.cli.robots import ModelDirOpt, SceneOpt
from mbctl.jobs.choices import TWO_LINK_ROBOTS


def verify(
    robot: Annotated[
        str, typer.Argument(help=f"Robot to check: {' or '.join(TWO_LINK_ROBOTS)}.")
    ] = "two_link",
) -> None:
    """Run the 2-link arm's setup checks (two_link or two_link_torque); exit 1 if any fails."""
    from mbctl.jobs.verify import verify_robot

    checks = verify_robot(robot)
    for c in checks:
        typer.echo(f"[{'PASS' if c.passed else 'FAIL'}] {c.name}: {c.detail}")
    failed = [c for c in checks if not c.passed]
    typer.echo(f"{len(checks) - len(failed)} passed, {len(failed)} failed")
    if failed:
        raise typer.Exit(1)


@with_options(MODEL_PARAMETERS)
def joint_step(
    robot: Annotated[str, typer.Argument(help="Known robot name or MJCF path.")],
    joint: Annotated[str, typer.Option(help="Joint whose position target is raised.")],
    delta: Annotated[float, typer.Option(help="Target increase (rad, or m for a slide joint).")],
    steps: Annotated[int, typer.Option(help="Physics steps to take.")] = 250,
    keyframe: Annotated[str | None, typer.Option(help="Keyframe to reset to (e.g. stand).")] = None,
    sensor: Annotated[list[str] | None, typer.Option(help="Sensor to record (repeatable).")] = None,
    scene: SceneOpt = None,
    model_dir: ModelDirOpt = None,
    output: OutputOpt = None,
    quiet: QuietOpt = False,
    video: VideoOpt = False,
    video_size: VideoSizeOpt = "640x480",
    extra: dict[str, Any] | None = None,
) -> None:
    """Reset, raise one joint's position target by DELTA, step N times, record, summarize."""
    from mbctl.jobs import options
    from mbctl.jobs.joint_step import JOINT_STEP

    params = options.joint_step(robot=robot, joint=joint, delta=delta, steps=steps, keyframe=keyframe,
                                sensor=sensor, scene=scene, model_dir=model_dir, **(extra or {}))
    execute(JOINT_STEP, params, output, quiet, video_spec(video, video_size))


def register(app: typer.Typer) -> None:
    """Add this module's commands to ``app``."""
    app.command("verify")(verify)
    app.command("joint-step")(joint_step)
