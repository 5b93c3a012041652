"""CLI: ``mbctl ik`` — solve inverse kinematics to convergence and write the pose as JSON.

``mbctl ik g1 --target left_palm=X,Y,Z --target right_palm=X,Y,Z [--com X,Y] --output DIR``
runs the G1 whole-body task set (feet held, palm targets, CoM, pelvis orientation, posture;
``mbctl.control.ik.whole_body``) on our Pinocchio QP. Any other robot gets position targets on any of
its frames, a posture regulariser and its joint limits.

Exit codes: 0 converged; 1 solved but not converged (unreachable target: the closest pose is
still written and the residuals say how far); 2 bad input.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from mbctl.control.exceptions import IKSetupError
from mbctl.exceptions import unknown_name_message


@dataclass(frozen=True)
class IKCommandConfig:
    """Inputs of ``mbctl ik`` after parsing.

    Attributes:
        robot: Robot name or MJCF path.
        targets: (frame, (x, y, z) [m]) pairs, world frame (offsets if ``relative``).
        com_xy: CoM target (x, y) [m] in the world, or None.
        relative: Targets are offsets from the start pose [m].
        output: Output directory.
        tol: Position tolerance [m].
        max_iters: Iteration cap.
        solver: qpsolvers backend.
        keyframe: Start keyframe (None: "stand" if present, else the neutral pose).
    """

    robot: str
    targets: tuple[tuple[str, tuple[float, float, float]], ...]
    com_xy: tuple[float, float] | None
    relative: bool
    output: Path
    tol: float
    max_iters: int
    solver: str
    keyframe: str | None


def parse_vector(text: str, n: int, what: str) -> tuple[float, ...]:
    """``"X,Y,Z"`` -> floats; IKSetupError naming ``what`` and the expected form otherwise."""
    parts = [p.strip() for p in text.split(",")]
    form = ",".join("XYZ"[:n]) if n <= 3 else f"{n} numbers"
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        values = ()
    if len(values) != n or not all(math.isfinite(v) for v in values):
        raise IKSetupError(
            f"{what} must be {n} finite numbers in metres as {form} (e.g. "
            f"{','.join(['0.3'] * n)}); got {text!r}"
        )
    return values


def parse_target(text: str) -> tuple[str, tuple[float, float, float]]:
    """``"frame=X,Y,Z"`` -> (frame, (x, y, z)); IKSetupError if malformed."""
    name, sep, vec = text.partition("=")
    if not sep or not name.strip():
        raise IKSetupError(f"--target must look like FRAME=X,Y,Z (e.g. left_palm=0.3,0.2,0.9); "
                           f"got {text!r}")
    xyz = parse_vector(vec, 3, f"--target {name.strip()}")
    return name.strip(), (xyz[0], xyz[1], xyz[2])


def _start_q(robot, keyframe: str | None) -> np.ndarray:
    if keyframe is not None:
        return robot.keyframe_q(keyframe)
    if "stand" in robot.keyframes:
        return robot.keyframe_q("stand")
    return robot.neutral_q()


def _solve_g1(robot, cfg: IKCommandConfig, q0: np.ndarray):
    from mbctl.control.ik.whole_body import PALM_SITES, PinocchioWholeBodyIK, with_palm_sites

    robot = with_palm_sites(robot)
    for name, _ in cfg.targets:
        if name not in PALM_SITES:
            raise IKSetupError(
                unknown_name_message("G1 IK target frame", name, PALM_SITES)
                + " (the feet are held at their start pose)"
            )
    wb = PinocchioWholeBodyIK(robot, q0, solver=cfg.solver)
    for name, xyz in cfg.targets:
        p = np.array(xyz)
        if cfg.relative:
            p = p + wb.frame_pose(name).translation
        wb.set_palm_target(name, p)
    if cfg.com_xy is not None:
        wb.set_com_target(np.array(cfg.com_xy) + (wb.state.com()[:2] if cfg.relative else 0.0))
    return robot, wb.ik, wb.position_limit, wb.config.dt


def _solve_generic(robot, cfg: IKCommandConfig, q0: np.ndarray):
    from mbctl.control import (
        ComTask,
        DiffIK,
        FloatingBaseVelocityLimit,
        FramePositionTask,
        IKState,
        JointPositionLimit,
        PostureTask,
    )
    from mbctl.control.ik.limits import Limit
    from mbctl.control.ik.tasks import Task

    model = robot.pin_model
    state = IKState(model, q0)
    tasks: list[Task] = []
    for name, xyz in cfg.targets:
        robot.frame_id(name)  # UnknownNameError with close matches
        task = FramePositionTask(name, model, cost=1.0, lm_damping=1.0, name=name)
        p = np.array(xyz)
        if cfg.relative:
            p = p + state.frame_pose(state.frame_id(name)).translation
        task.set_target(p)
        tasks.append(task)
    if cfg.com_xy is not None:
        com = ComTask([1.0, 1.0, 0.0])
        p = state.com().copy()
        p[:2] = np.array(cfg.com_xy) + (p[:2] if cfg.relative else 0.0)
        com.set_target(p)
        tasks.append(com)
    posture = PostureTask(model, 1e-2)
    posture.set_target(q0)
    tasks.append(posture)
    position_limit = JointPositionLimit(model)
    limits: list[Limit] = [position_limit]
    if robot.has_floating_base:
        limits.append(FloatingBaseVelocityLimit(model, 1.0, 2.0))
    return robot, DiffIK(model, tasks, limits, cfg.solver, 1e-6), position_limit, 1.0


def run_ik(cfg: IKCommandConfig) -> int:
    """Solve, print the report, write ``DIR/ik_pose.json``; return the exit code (0 or 1)."""
    from mbctl.robots import load_robot
    from mbctl.robots.exceptions import UnknownNameError

    if not cfg.targets and cfg.com_xy is None:
        raise IKSetupError("Give at least one --target FRAME=X,Y,Z (or --com X,Y).")
    robot = load_robot(cfg.robot)
    q0 = _start_q(robot, cfg.keyframe)
    try:
        if robot.name == "g1":
            robot, ik, position_limit, dt = _solve_g1(robot, cfg, q0)
        else:
            robot, ik, position_limit, dt = _solve_generic(robot, cfg, q0)
    except UnknownNameError as exc:
        raise IKSetupError(str(exc)) from None
    t0 = time.perf_counter()
    res = ik.solve(q0, dt=dt, tol=cfg.tol, tol_rad=10 * cfg.tol, max_iters=cfg.max_iters)
    elapsed = time.perf_counter() - t0

    status = "converged" if res.converged else ("stalled (closest pose)" if res.stalled else
                                                 "NOT converged (iteration cap)")
    typer.echo(f"robot {robot.name}: {status} in {res.iterations} iterations, "
               f"{elapsed * 1e3:.1f} ms ({elapsed / max(res.iterations, 1) * 1e6:.0f} us/iteration),"
               f" solver {cfg.solver}, tol {cfg.tol:g} m")
    typer.echo("task residuals:")
    regularisers = {t.name for t in ik.tasks if t.regularizing}
    for task, values in res.residuals.items():
        text = ", ".join(f"{k.split(' ')[0]} {v:.3e} {k.split(' ')[1]}" if " " in k else
                         f"{k} {v:.3e}" for k, v in values.items())
        note = "  (regulariser, not a target)" if task in regularisers else ""
        typer.echo(f"  {task:20s} {text}{note}")
    margins = position_limit.margins(res.q)
    closest = sorted(margins.items(), key=lambda kv: min(kv[1]))[:5]
    if closest:
        typer.echo("joint-limit margins (closest 5; to lower, to upper) [rad or m]:")
        for name, (lo, hi) in closest:
            typer.echo(f"  {name:28s} {lo:+.4f} {hi:+.4f}")
    else:
        typer.echo("joint-limit margins: no joint has finite position limits")
    cfg.output.mkdir(parents=True, exist_ok=True)
    out = cfg.output / "ik_pose.json"
    q_by_joint = {
        j.name: res.q[j.idx_q : j.idx_q + j.nq].tolist() for j in robot.joints.values()
    }
    payload = {
        "robot": robot.name,
        "convention": "Pinocchio (free joint: x, y, z, qx, qy, qz, qw)",
        "converged": bool(res.converged),
        "iterations": res.iterations,
        "wall_time_s": elapsed,
        "solver": cfg.solver,
        "tolerance_m": cfg.tol,
        "targets": {name: list(xyz) for name, xyz in cfg.targets},
        "targets_relative": cfg.relative,
        "com_xy": list(cfg.com_xy) if cfg.com_xy is not None else None,
        "residuals": res.residuals,
        "min_joint_limit_margin": min(min(v) for v in margins.values()) if margins else None,
        "q": q_by_joint,
        "model_edits": list(robot.source.edits),
    }
    out.write_text(json.dumps(payload, indent=2))
    typer.echo(f"pose written to {out}")
    return 0 if res.converged else 1


def ik(
    robot: Annotated[str, typer.Argument(help="Robot: g1 (whole-body task set) or any robot/MJCF.")],
    target: Annotated[
        list[str] | None,
        typer.Option("--target", help="FRAME=X,Y,Z world position [m] (repeatable)."),
    ] = None,
    com: Annotated[str | None, typer.Option("--com", help="CoM target X,Y [m] (world).")] = None,
    output: Annotated[Path, typer.Option("--output", help="Directory for ik_pose.json.")] = Path(
        "ik_out"
    ),
    tol: Annotated[float, typer.Option("--tol", help="Position tolerance [m].")] = 1e-3,
    max_iters: Annotated[int, typer.Option("--max-iters", help="Iteration cap.")] = 50,
    solver: Annotated[str, typer.Option("--solver", help="QP backend: daqp or osqp.")] = "daqp",
    relative: Annotated[
        bool, typer.Option("--relative", help="Targets are offsets from the start pose [m].")
    ] = False,
    keyframe: Annotated[
        str | None, typer.Option("--keyframe", help="Start keyframe (default: stand/neutral).")
    ] = None,
) -> None:
    """Solve IK to convergence; print residuals, joint-limit margins, iterations and time."""
    if solver not in ("daqp", "osqp"):
        raise IKSetupError(f"--solver must be daqp or osqp; got {solver!r}")
    if not (math.isfinite(tol) and tol > 0):
        raise IKSetupError(f"--tol must be a positive length [m]; got {tol!r}")
    if max_iters < 1:
        raise IKSetupError(f"--max-iters must be >= 1; got {max_iters!r}")
    cfg = IKCommandConfig(
        robot=robot,
        targets=tuple(parse_target(t) for t in (target or [])),
        com_xy=tuple(parse_vector(com, 2, "--com")) if com is not None else None,  # type: ignore[arg-type]
        relative=relative,
        output=output,
        tol=tol,
        max_iters=max_iters,
        solver=solver,
        keyframe=keyframe,
    )
    code = run_ik(cfg)
    if code:
        raise typer.Exit(code)


def workspace(
    robot: Annotated[str, typer.Argument(help="two_link or two_link_torque.")] = "two_link",
    output: Annotated[Path, typer.Option(help="Output directory for workspace.png.")] = Path("out/workspace"),
) -> None:
    """The 2-link arm's reachable annulus (r_min, r_max) and a sampled workspace plot (PNG)."""
    from mbctl.control.ik.two_link import TwoLinkArm, plot_workspace
    from mbctl.robots import load_robot

    model = load_robot(robot)
    arm = TwoLinkArm.from_robot(model)
    path = plot_workspace(arm, output / "workspace.png", robot=model)
    typer.echo(
        f"links {arm.link1_length:.4f} m and {arm.link2_length:.4f} m (to the site); reachable "
        f"annulus r_min = {arm.r_min:.4f} m, r_max = {arm.r_max:.4f} m around the shoulder"
    )
    typer.echo(f"wrote {path}")


def register(app: typer.Typer) -> None:
    """Add ``mbctl ik`` and ``mbctl workspace`` to ``app``."""
    app.command("ik")(ik)
    app.command("workspace")(workspace)
