"""CLI: ``mbctl verify`` and ``mbctl joint-step`` — the plant's setup checks and a joint step."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from mbctl.jobs.joint_step import joint_step as run_joint_step
from mbctl.jobs.verify import verify_two_link
from mbctl.robots import load_robot


def verify(
    robot: Annotated[str, typer.Argument(help="two_link")] = "two_link",
) -> None:
    """Run the 2-link setup checks; exit 1 if any fails."""
    if robot != "two_link":
        typer.echo(f"error: verify runs the 2-link setup checks; got {robot!r} (use two_link)", err=True)
        raise typer.Exit(2)
    checks = verify_two_link(load_robot(robot))
    for c in checks:
        typer.echo(f"[{'PASS' if c.passed else 'FAIL'}] {c.name}: {c.detail}")
    failed = [c for c in checks if not c.passed]
    typer.echo(f"{len(checks) - len(failed)} passed, {len(failed)} failed")
    if failed:
        raise typer.Exit(1)


def joint_step(
    robot: Annotated[str, typer.Argument(help="Known robot name or MJCF path.")],
    joint: Annotated[str, typer.Option(help="Joint whose position target is raised.")],
    delta: Annotated[float, typer.Option(help="Target increase [rad].")],
    steps: Annotated[int, typer.Option(help="Physics steps to take.")] = 250,
    keyframe: Annotated[str | None, typer.Option(help="Keyframe to reset to (e.g. stand).")] = None,
    output: Annotated[Path, typer.Option(help="Output directory for CSV and JSON.")] = Path("out"),
    sensor: Annotated[list[str] | None, typer.Option(help="Sensor to record (repeatable).")] = None,
    scene: Annotated[str | None, typer.Option(help="Scene MJCF when ROBOT is a path.")] = None,
) -> None:
    """Reset, raise one joint's position target by DELTA, step N times, record, summarize."""
    result = run_joint_step(
        load_robot(robot, scene), joint, delta, steps, output, keyframe=keyframe,
        sensors=tuple(sensor or ()),
    )
    typer.echo(result.summary())


def register(app: typer.Typer) -> None:
    """Add this module's commands to ``app``."""
    app.command("verify")(verify)
    app.command("joint-step")(joint_step)
