"""CLI: ``mbctl xcheck`` — cross-validate a robot's Pinocchio dynamics against its MuJoCo plant."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import typer

from mbctl.robots import load_robot
from mbctl.robots.crosscheck.evaluate import crosscheck
from mbctl.robots.crosscheck.report import Report


@dataclass(frozen=True)
class XcheckConfig:
    """What ``mbctl xcheck`` runs.

    Attributes:
        robot: Known robot name or MJCF robot file (Pinocchio reads it unless ``pin_model``).
        scene: Scene MJCF for MuJoCo that includes the robot (paths only).
        states: Number of random states (edge states are added).
        seed: Seed of the random states.
        json_path: Where to write the report as JSON, or None.
        pin_model: Alternative file (MJCF or URDF) for the Pinocchio side, or None.
        gravity: Switch on the robot's gravity (the 2-link arm's is off by default).
    """

    robot: str
    scene: str | None = None
    states: int = 100
    seed: int = 0
    json_path: Path | None = None
    pin_model: Path | None = None
    gravity: bool = False


def run(config: XcheckConfig) -> Report:
    """Load the pair without the agreement check (the report carries its findings) and compare.

    Raises:
        ToolkitError: The robot cannot be found or loaded, or the arguments are invalid.
    """
    robot = load_robot(
        config.robot,
        config.scene,
        gravity=True if config.gravity else None,
        pin_model_file=config.pin_model,
        check=False,
    )
    report = crosscheck(robot, n_states=config.states, seed=config.seed)
    if config.json_path is not None:
        config.json_path.parent.mkdir(parents=True, exist_ok=True)
        config.json_path.write_text(json.dumps(report.to_dict(), indent=2) + "\n")
    return report


def xcheck(
    robot: Annotated[str, typer.Argument(help="Known robot name or MJCF robot file.")],
    scene: Annotated[
        str | None, typer.Option("--scene", help="Scene MJCF for MuJoCo, when ROBOT is a path.")
    ] = None,
    states: Annotated[int, typer.Option("--states", min=0, help="Number of random states.")] = 100,
    seed: Annotated[int, typer.Option("--seed", min=0, help="Seed of the random states.")] = 0,
    json_path: Annotated[
        Path | None, typer.Option("--json", help="Also write the report as JSON to this file.")
    ] = None,
    pin_model: Annotated[
        Path | None,
        typer.Option("--pin-model", help="Build the Pinocchio side from this MJCF or URDF file."),
    ] = None,
    gravity: Annotated[
        bool, typer.Option("--gravity", help="Switch on the robot's gravity (2-link arm: -y).")
    ] = False,
) -> None:
    """Compare kinematics and dynamics of Pinocchio and MuJoCo; exit 1 if any quantity fails."""
    report = run(XcheckConfig(robot, scene, states, seed, json_path, pin_model, gravity))
    typer.echo(report.to_text())
    if not report.passed:
        raise typer.Exit(1)


def register(app: typer.Typer) -> None:
    """Add this module's commands to ``app``."""
    app.command("xcheck")(xcheck)
