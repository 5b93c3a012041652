"""CLI: ``mbctl robots`` and ``mbctl inspect`` — what robots exist and what is in them."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Annotated

import typer

if TYPE_CHECKING:
    from mbctl.robots import Robot

ModelDirOpt = Annotated[
    str | None,
    typer.Option("--model-dir", help="Explicit Menagerie model directory (e.g. .../unitree_g1)."),
]
#: ``--model-error``: the controller's model with its link masses scaled.
ModelErrorOpt = Annotated[
    float, typer.Option("--model-error", help="Controller model link masses off by PCT (%).")
]
RobotArg = Annotated[str, typer.Argument(help="Known robot name (see `mbctl robots`) or MJCF path.")]
SceneOpt = Annotated[
    str | None,
    typer.Option("--scene", help="Scene MJCF for MuJoCo that includes the robot (default: the robot's own)."),
]
RootOpt = Annotated[
    list[str] | None,
    typer.Option("--root", help="A body of the robot (repeatable): its tree is the robot; the rest of the "
                                "plant is scene (default: the trees the actuators drive)."),
]


def robots() -> None:
    """List the known robots and where each model comes from."""
    from mbctl.robots import KNOWN_ROBOTS

    for known in KNOWN_ROBOTS.values():
        typer.echo(f"{known.name:16s} {known.description}")
        typer.echo(f"{'':16s} source: {known.origin}")
    typer.echo("Any other MJCF robot: pass its path (and --scene for a scene that includes it).")


def _range(lo: float, hi: float) -> str:
    return "unlimited" if not (math.isfinite(lo) and math.isfinite(hi)) else f"[{lo:g}, {hi:g}]"


def describe(robot: Robot) -> str:
    """A side-by-side text description of both engines' view of ``robot``."""
    import mujoco
    import numpy as np

    pm, m = robot.pin_model, robot.mj_model
    lines = [
        f"robot: {robot.name}  ({robot.source.origin})",
        f"  robot file:     {robot.source.robot_file}",
        f"  MuJoCo file:    {robot.source.scene_file}",
    ]
    built = "built from the compiled MuJoCo model" if robot.source.analytic == "mujoco" else "parser"
    lines.append(f"  Pinocchio model: {built}")
    lines += [f"  load-time edit: {e}" for e in robot.source.edits]
    pin_mass = sum(i.mass for i in pm.inertias)
    mj_mass = float(np.sum(m.body_mass[list(robot.robot_body_ids)]))
    if np.isclose(pin_mass, mj_mass, rtol=1e-9, atol=0):
        pin_mass = mj_mass  # equal up to summation order: print one number, not 58.1882 vs 58.1883
    lines += [
        f"{'robot':18s}{'Pinocchio':>12s}{'MuJoCo':>12s}",
        f"{'nq':18s}{pm.nq:12d}{robot.converter.nq:12d}",
        f"{'nv':18s}{pm.nv:12d}{robot.converter.nv:12d}",
        f"{'nu (actuators)':18s}{'-':>12s}{m.nu:12d}",
        f"{'mass (kg)':18s}{pin_mass:12.4f}{mj_mass:12.4f}",
        f"{'timestep (s)':18s}{'-':>12s}{m.opt.timestep:12g}",
        f"{'integrator':18s}{'-':>12s} {mujoco.mjtIntegrator(m.opt.integrator).name[6:]:>11s}",
        "joints (name, type, q slice, v slice, Pinocchio joint type, armature):",
    ]
    for j in robot.joints.values():
        jid = pm.getJointId(j.name) if pm.existJointName(j.name) else -1
        pin_type = pm.joints[jid].shortname() if jid >= 0 else "missing"
        arm = float(m.dof_armature[j.dofadr])
        lines.append(
            f"  {j.name:28s} {j.kind:6s} q[{j.q_slice.start}:{j.q_slice.stop}] "
            f"v[{j.v_slice.start}:{j.v_slice.stop}]  {pin_type:22s} armature {arm:g}"
        )
    by_kind: dict[str, int] = {}
    for j in robot.joints.values():
        by_kind[j.kind] = by_kind.get(j.kind, 0) + 1
    lines.append("joints by type: " + ", ".join(f"{k} {n}" for k, n in by_kind.items()))
    lines.append("actuators (name, joint or transmission, kind, gear, kp, kv, ctrl range, force range):")
    for a in robot.actuators.values():
        scale = f" target {a.target_per_ctrl:.4g} x ctrl" if a.target_per_ctrl != 1.0 else ""
        lines.append(
            f"  {a.name:28s} {a.joint or a.transmission:28s} {a.kind:8s} gear {a.gear:g} kp {a.kp:g} "
            f"kv {a.kv:.4g} ctrl {_range(*a.ctrl_range)} force {_range(*a.force_range)}{scale}"
        )
    lines.append("sensors (name, type, dim):")
    lines += [f"  {s.name:36s} {s.type:16s} {s.dim}" for s in robot.sensors.values()]
    lines.append(f"sites: {', '.join(robot.sites) or '-'}")
    lines.append(f"keyframes: {', '.join(robot.keyframes) or '-'}")
    if robot.scene_body_ids:
        lines.append(
            f"scene (in the plant, not the robot; plant nq {m.nq}, nv {m.nv}, "
            f"{float(np.sum(m.body_mass)):.4f} kg in all):"
        )
        lines += [f"  {b}" for b in robot.scene_bodies]
    return "\n".join(lines)


def inspect(
    robot: RobotArg, scene: SceneOpt = None, model_dir: ModelDirOpt = None, root: RootOpt = None
) -> None:
    """Show nq, nv, nu, joints, actuators, sensors, keyframes and the scene in both engines."""
    from mbctl.robots import load_robot

    typer.echo(describe(load_robot(robot, scene, model_dir=model_dir, roots=root or ())))


def register(app: typer.Typer) -> None:
    """Add this module's commands to ``app``."""
    app.command("robots")(robots)
    app.command("inspect")(inspect)
