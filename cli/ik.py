"""CLI: ``mbctl ik`` and ``mbctl workspace`` — argument parsing only (the work is in ``mbctl.jobs``).

``mbctl ik ROBOT --target FRAME=X,Y,Z ... [--com X,Y] [--backend qp|mink]`` runs
:data:`mbctl.jobs.ik.IK`; ``mbctl workspace [two_link|two_link_torque]`` runs
:data:`mbctl.jobs.workspace.WORKSPACE`.

Exit codes: 0 converged; 1 solved but not converged (unreachable target, a singular start, or
the MuJoCo plant disagrees with the IK's model: the last pose is still written and the residuals
say how far); 2 bad input.
"""

from __future__ import annotations

from typing import Annotated

import typer

from mbctl.cli._run import OutputOpt, QuietOpt, execute
from mbctl.cli.robots import ModelDirOpt, RootOpt, SceneOpt
from mbctl.jobs.choices import TWO_LINK_ROBOTS


def ik(
    robot: Annotated[str, typer.Argument(
        help="Known robot name or MJCF file. The Menagerie G1 (name g1) gets the whole-body set "
             "(feet held, palms, CoM, pelvis); any other robot position targets on its sites/bodies.")],
    target: Annotated[
        list[str] | None,
        typer.Option("--target", help="FRAME=X,Y,Z world position (m) of a site or body (repeatable)."),
    ] = None,
    com: Annotated[str | None, typer.Option("--com", help="CoM target X,Y (m), world frame.")] = None,
    backend: Annotated[
        str, typer.Option("--backend", help="IK backend: qp (ours, on Pinocchio) or mink (on MuJoCo).")
    ] = "qp",
    tol: Annotated[
        float, typer.Option("--tol", help="Position tolerance (m), checked in MuJoCo too.")
    ] = 1e-3,
    max_iters: Annotated[int, typer.Option("--max-iters", help="Iteration cap.")] = 50,
    solver: Annotated[str, typer.Option("--solver", help="QP solver: daqp or osqp.")] = "daqp",
    relative: Annotated[
        bool, typer.Option("--relative", help="Targets are offsets (m) from the start pose.")
    ] = False,
    keyframe: Annotated[
        str | None,
        typer.Option("--keyframe", help="Start keyframe (default: stand for the G1, else neutral)."),
    ] = None,
    scene: SceneOpt = None,
    model_dir: ModelDirOpt = None,
    root: RootOpt = None,
    output: OutputOpt = None,
    quiet: QuietOpt = False,
) -> None:
    """Solve IK to convergence, check the pose in MuJoCo, write ik_pose.json; exit 1 if not converged."""
    from mbctl.jobs import options
    from mbctl.jobs.ik import IK

    params = options.ik(robot=robot, target=target, com=com, backend=backend, tol=tol, max_iters=max_iters,
                        solver=solver, relative=relative, keyframe=keyframe, scene=scene, model_dir=model_dir,
                        root=root)
    execute(IK, params, output, quiet)


def workspace(
    robot: Annotated[str, typer.Argument(
        help=f"The 2-link arm only: {' or '.join(TWO_LINK_ROBOTS)}; other robots are refused."),
    ] = "two_link",
    samples: Annotated[int, typer.Option("--samples", min=2, help="Grid samples per joint.")] = 121,
    output: OutputOpt = None,
    quiet: QuietOpt = False,
) -> None:
    """The 2-link arm's reachable annulus r_min, r_max (m) and a sampled workspace plot (PNG).

    Supports only the planar 2-link arm (two_link, two_link_torque); other robots are refused.
    """
    from mbctl.jobs import options
    from mbctl.jobs.workspace import WORKSPACE

    execute(WORKSPACE, options.workspace(robot=robot, samples=samples), output, quiet)


def register(app: typer.Typer) -> None:
    """Add ``mbctl ik`` and ``mbctl workspace`` to ``app``."""
    app.command("ik")(ik)
    app.command("workspace")(workspace)
