"""CLI: ``mbctl xcheck`` — cross-validate a robot's Pinocchio dynamics against its MuJoCo plant."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from mbctl.cli._run import OutputOpt, QuietOpt, execute
from mbctl.cli.robots import ModelDirOpt, RootOpt, SceneOpt
from mbctl.jobs import options
from mbctl.jobs.xcheck import XCHECK


def xcheck(
    robot: Annotated[str, typer.Argument(help="Known robot name or MJCF robot file.")],
    scene: SceneOpt = None,
    states: Annotated[int, typer.Option("--states", min=0, help="Number of random states.")] = 100,
    seed: Annotated[int, typer.Option("--seed", min=0, help="Seed of the random states.")] = 0,
    json_path: Annotated[
        Path | None, typer.Option("--json", help="Also write the cross-check report as JSON to this file.")
    ] = None,
    pin_model: Annotated[
        Path | None,
        typer.Option("--pin-model", help="Build the Pinocchio side from this MJCF or URDF file."),
    ] = None,
    gravity: Annotated[
        bool, typer.Option("--gravity/--no-gravity", help="Gravity on (2-link arm: -y) or as loaded.")
    ] = False,
    model_dir: ModelDirOpt = None,
    analytic: Annotated[
        str, typer.Option("--analytic", help="Pinocchio model: mujoco (from the compiled plant) or parser.")
    ] = "mujoco",
    root: RootOpt = None,
    joint_map: Annotated[
        str | None,
        typer.Option("--joint-map", metavar="FILE|A=B,...",
                     help="With --pin-model: joints named differently, PIN_FILE_JOINT=MJCF_JOINT (inline, "
                          "comma-separated, or a file of such lines)."),
    ] = None,
    floating_base: Annotated[
        bool | None,
        typer.Option("--floating-base/--fixed-base",
                     help="With --pin-model: add a free flyer to a fixed-base file, or never; default: "
                          "added when the MJCF's robot has a free root joint."),
    ] = None,
    output: OutputOpt = None,
    quiet: QuietOpt = False,
) -> None:
    """Compare kinematics and dynamics of Pinocchio and MuJoCo; exit 1 if any quantity fails."""
    params = options.xcheck(robot=robot, scene=scene, states=states, seed=seed, json_path=json_path,
                            pin_model=pin_model, gravity=gravity, model_dir=model_dir, analytic=analytic,
                            root=root, joint_map=joint_map, floating_base=floating_base)
    execute(XCHECK, params, output, quiet)


def register(app: typer.Typer) -> None:
    """Add this module's commands to ``app``."""
    app.command("xcheck")(xcheck)
