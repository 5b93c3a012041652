"""The ``mbctl ik`` job: solve whole-body IK to convergence, check it on the MuJoCo plant.

Task set. The robot that IS the Menagerie G1 (``mbctl.robots.g1.is_menagerie_g1``: loaded by the
registry name "g1", told apart by its recorded origin, never by the file stem) gets the G1 set:
palm sites added at load time, feet held, palm position targets, CoM (x, y), pelvis orientation,
posture. Any other robot (a user file named g1.xml included) gets the generic set: position
targets on any of its MuJoCo sites or bodies, optional CoM (x, y), posture, joint limits.
Both sets run on either backend, ``qp`` (our Pinocchio QP) or ``mink``
(:func:`mbctl.control.ik.make_whole_body_ik`), through the one IK loop.

Plant check (never a silent wrong answer). After solving, the pose is converted to MuJoCo's
convention (``robot.converter.q_pin_to_mj``), ``mj_kinematics`` and ``mj_comPos`` run on a scratch
``MjData`` of ``robot.mj_model``, and every position target (held and target frames, CoM x-y) is
measured there: ``plant_residual_m``; so is every held orientation (held frames, base frame):
``plant_residual_rad``. The run is ``converged`` only when the IK's own residuals AND the plant
residuals are within tolerance (``tol_m``; ``10 * tol_m`` rad for orientations); otherwise the
pose is still written and the run exits 1.

Outputs: ``ik_pose.json`` (pose by joint, residuals, plant residuals) and the runner's
``report.json``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import mujoco
import numpy as np
import pinocchio as pin

from mbctl.control.exceptions import IKSetupError
from mbctl.control.ik import (
    BACKENDS,
    IKResult,
    WholeBodyIK,
    WholeBodyIKConfig,
    joint_positions_by_name,
    make_whole_body_ik,
    mujoco_frame_type,
)
from mbctl.control.tasks import Tolerance, residual_table
from mbctl.exceptions import unknown_name_message
from mbctl.jobs.runner import Job, Outcome, RunContext, Work
from mbctl.robots.exceptions import UnknownNameError
from mbctl.robots.g1 import FEET, KEYFRAME, PALM_SITES, PELVIS, is_menagerie_g1, with_palm_sites
from mbctl.robots.model_pair import Robot
from mbctl.robots.registry import KNOWN_ROBOTS, load_robot
from mbctl.sim.atomic import write_json_atomic

#: QP backends of qpsolvers that ``mbctl ik`` offers.
SOLVERS = ("daqp", "osqp")

#: Orientation tolerance [rad] per metre of position tolerance (as ``WholeBodyIK.solve``).
RAD_PER_M_TOL = 10.0


@dataclass(frozen=True)
class IKParams:
    """What ``mbctl ik`` solves.

    Attributes:
        robot: Known robot name or MJCF robot file.
        targets: (frame, (x, y, z) (m)) pairs, world frame (offsets from the start if ``relative``).
        com_xy: CoM target (x, y) (m) in the world, or None.
        relative: Targets are offsets from the start pose (m).
        tol_m: Position tolerance (m); orientations get ``RAD_PER_M_TOL * tol_m`` (rad).
        max_iters: Iteration cap.
        solver: qpsolvers backend (``SOLVERS``).
        backend: IK backend (``BACKENDS``: "qp" or "mink").
        keyframe: Start keyframe (None: "stand" for the G1, else the neutral pose).
        scene: Scene MJCF for MuJoCo that includes the robot (default: the robot's own).
        model_dir: Explicit Menagerie model directory for a known robot.
        roots: Bodies whose trees are the robot (default: the trees the actuators drive).
    """

    robot: str
    targets: tuple[tuple[str, tuple[float, float, float]], ...] = ()
    com_xy: tuple[float, float] | None = None
    relative: bool = False
    tol_m: float = 1e-3
    max_iters: int = 50
    solver: str = "daqp"
    backend: str = "qp"
    keyframe: str | None = None
    scene: str | None = None
    model_dir: str | None = None
    roots: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if not self.targets and self.com_xy is None:
            raise IKSetupError("Give at least one --target FRAME=X,Y,Z (or --com X,Y).")
        if self.solver not in SOLVERS:
            raise IKSetupError(f"solver must be one of {', '.join(SOLVERS)}; got {self.solver!r}")
        if self.backend not in BACKENDS:
            raise IKSetupError(f"backend must be one of {', '.join(BACKENDS)}; got {self.backend!r}")
        if not (math.isfinite(self.tol_m) and self.tol_m > 0):
            raise IKSetupError(f"tol must be a positive length (m); got {self.tol_m!r}")
        if int(self.max_iters) < 1:
            raise IKSetupError(f"max_iters must be >= 1; got {self.max_iters!r}")
        names = [name for name, _ in self.targets]
        repeated = sorted({n for n in names if names.count(n) > 1})
        if repeated:
            raise IKSetupError(f"frames {repeated} have more than one --target; give one each")
        for name, xyz in self.targets:
            if len(xyz) != 3 or not all(math.isfinite(v) for v in xyz):
                raise IKSetupError(f"target of {name!r} must be 3 finite numbers (m); got {xyz!r}")
        if self.com_xy is not None and (len(self.com_xy) != 2 or
                                        not all(math.isfinite(v) for v in self.com_xy)):
            raise IKSetupError(f"com must be 2 finite numbers (m); got {self.com_xy!r}")
        if self.model_dir is not None and self.robot not in KNOWN_ROBOTS:
            raise IKSetupError(
                f"--model-dir applies only to a known robot ({', '.join(KNOWN_ROBOTS)}); "
                f"{self.robot!r} is a path: drop --model-dir"
            )

    @property
    def tol_rad(self) -> float:
        """Orientation tolerance [rad]."""
        return RAD_PER_M_TOL * self.tol_m


def g1_config(**weights: float) -> WholeBodyIKConfig:
    """The G1 whole-body task set (mink's humanoid example): feet held, palm targets, CoM, pelvis.

    Args:
        **weights: Overrides of ``WholeBodyIKConfig``'s weights and limits.
    """
    return WholeBodyIKConfig(held_frames=FEET, target_frames=tuple(PALM_SITES), base_frame=PELVIS,
                             com=True, **weights)  # type: ignore[arg-type]


def generic_config(targets: tuple[str, ...], com: bool) -> WholeBodyIKConfig:
    """The generic task set: position targets on ``targets``, optional CoM, posture, limits.

    The target weight (5 per m, as the G1's palms) is 500 times the posture weight, so the
    regulariser's pull leaves well under 0.1 mm of bias on a reachable target near the start.
    Joint limits: positions, a per-joint step of at most 2 rad (or m) per iteration (a trust
    region: without it a step near a singular pose can spin an unlimited joint by tens of
    radians, and the posture regulariser then pulls the solution off its target) and, for a
    floating base, the base speed limits.
    """
    return WholeBodyIKConfig(target_frames=targets, com=com, target_position_cost=5.0,
                             posture_cost=1e-2, damping=1e-6, joint_max_velocity=2.0)


def task_set_for(robot: Robot, params: IKParams) -> tuple[Robot, WholeBodyIKConfig, str]:
    """The robot (palm sites added for the G1), its task set and the set's name ("g1" or "generic").

    Raises:
        IKSetupError: A target frame the task set does not have (the message lists them).
    """
    names = tuple(name for name, _ in params.targets)
    if is_menagerie_g1(robot):
        robot = with_palm_sites(robot)
        for name in names:
            if name not in PALM_SITES:
                raise IKSetupError(unknown_name_message("G1 IK target frame", name, PALM_SITES)
                                   + " (the feet are held at their start pose)")
        return robot, g1_config(), "g1"
    for name in names:
        mujoco_frame_type(robot, name)
    return robot, generic_config(names, params.com_xy is not None), "generic"


def start_q(robot: Robot, keyframe: str | None, task_set: str) -> np.ndarray:
    """Start configuration (nq,): ``keyframe``, else the G1's "stand", else the neutral pose."""
    if keyframe is not None:
        return robot.keyframe_q(keyframe)
    if task_set == "g1":
        return robot.keyframe_q(KEYFRAME)
    return robot.neutral_q()


class PlantFrames(NamedTuple):
    """Frames measured on the MuJoCo plant (``mj_kinematics`` + ``mj_comPos``, never stepped).

    Attributes:
        positions: p_WF (3,) [m] by frame, world frame.
        rotations: R_WF (3, 3) by frame, world frame.
        com: Centre of mass p_WC (3,) [m] of the whole model, world frame.
    """

    positions: dict[str, np.ndarray]
    rotations: dict[str, np.ndarray]
    com: np.ndarray


class PlantResiduals(NamedTuple):
    """How far the plant (MuJoCo) is from each target at the IK's pose.

    Attributes:
        position_m: Distance [m] from each position target (frames; CoM x-y as ``"com"``).
        orientation_rad: Rotation angle [rad] from each held orientation (held and base frames).
    """

    position_m: dict[str, float]
    orientation_rad: dict[str, float]

    def within(self, tol_m: float, tol_rad: float) -> bool:
        """Every position residual <= ``tol_m`` [m] and every angle <= ``tol_rad`` [rad]."""
        return (max(self.position_m.values(), default=0.0) <= tol_m
                and max(self.orientation_rad.values(), default=0.0) <= tol_rad)


def plant_frames(robot: Robot, q: np.ndarray, frames: tuple[str, ...]) -> PlantFrames:
    """Poses of ``frames`` and the CoM from MuJoCo's own kinematics on a scratch ``MjData``.

    Args:
        robot: The model pair (its ``mj_model`` is read, never stepped).
        q: Configuration (nq,), Pinocchio convention (converted with ``robot.converter``).
        frames: MuJoCo sites or bodies.

    Raises:
        IKSetupError: A frame that is neither a site nor a body (the message lists them).
    """
    m = robot.mj_model
    data = mujoco.MjData(m)
    robot.plant_qpos(q, data.qpos)
    mujoco.mj_kinematics(m, data)
    mujoco.mj_comPos(m, data)
    positions, rotations = {}, {}
    for frame in frames:
        if mujoco_frame_type(robot, frame) == "site":
            i = robot.site_id(frame)
            positions[frame], rotations[frame] = data.site_xpos[i].copy(), data.site_xmat[i].reshape(3, 3)
        else:
            i = robot.body_id(frame)
            positions[frame], rotations[frame] = data.xpos[i].copy(), data.xmat[i].reshape(3, 3)
    return PlantFrames(positions, {f: R.copy() for f, R in rotations.items()},
                       data.subtree_com[0].copy())


def plant_residuals(robot: Robot, ik: WholeBodyIK, q: np.ndarray) -> PlantResiduals:
    """Residuals of the IK's targets measured on the MuJoCo plant at ``q`` (nq,), Pinocchio."""
    positions, rotations = ik.target_positions(), ik.target_rotations()
    plant = plant_frames(robot, q, tuple(dict.fromkeys([*positions, *rotations])))
    out = {f: float(np.linalg.norm(plant.positions[f] - p)) for f, p in positions.items()}
    com_target = ik.com_target
    if com_target is not None:
        out["com"] = float(np.linalg.norm(plant.com[:2] - com_target[:2]))
    angles = {f: float(np.linalg.norm(pin.log3(R_WT.T @ plant.rotations[f])))
              for f, R_WT in rotations.items()}
    return PlantResiduals(out, angles)


def prepare(params: IKParams, robot: Robot | None = None) -> Work:
    """Load the robot, choose the task set, build the backend and set the targets (no output yet).

    Args:
        params: The job's parameters.
        robot: An already loaded model pair to use instead of loading ``params.robot`` (tests).

    Raises:
        IKSetupError: Unknown target frame, backend setup failure.
        ToolkitError: The robot cannot be found or loaded.
    """
    if robot is None:
        robot = load_robot(params.robot, params.scene, model_dir=params.model_dir, roots=params.roots)
    try:
        robot, config, task_set = task_set_for(robot, params)
        q0 = start_q(robot, params.keyframe, task_set)
    except UnknownNameError as exc:
        raise IKSetupError(str(exc)) from None
    ik = make_whole_body_ik(params.backend, robot, config, q0, params.solver)
    for name, xyz in params.targets:
        p = np.array(xyz, dtype=float)
        ik.set_target_position(name, p + ik.frame_position(name) if params.relative else p)
    if params.com_xy is not None:
        xy = np.array(params.com_xy, dtype=float)
        ik.set_com_target(xy + ik.com()[:2] if params.relative else xy)

    def work(ctx: RunContext) -> Outcome:
        res = ik.solve(q0, Tolerance(params.tol_m, params.tol_rad), max_iters=params.max_iters)
        plant = plant_residuals(robot, ik, res.q)
        converged = bool(res.converged and plant.within(params.tol_m, params.tol_rad))
        margins = ik.position_limit.margins(res.q)
        min_margin = min(min(v) for v in margins.values()) if margins else None
        per_iteration_s = float(np.median(res.iteration_times_s)) if res.iterations else None
        ctx.sections["inputs"] = {"task_set": task_set, "backend": params.backend,
                                  "model_edits": list(robot.source.edits)}
        ctx.values.update({
            "converged": converged,
            "ik_converged": bool(res.converged),
            "iterations": res.iterations,
            "wall_time_s": res.wall_time_s,
            "median_iteration_time_s": per_iteration_s,
            "max_plant_residual_m": max(plant.position_m.values(), default=0.0),
            "max_plant_residual_rad": max(plant.orientation_rad.values(), default=0.0),
            "min_joint_limit_margin": min_margin,
        })
        payload: dict[str, Any] = {
            "robot": robot.name,
            "origin": robot.source.origin,
            "task_set": task_set,
            "backend": params.backend,
            "solver": params.solver,
            "convention": "Pinocchio (free joint: x, y, z, qx, qy, qz, qw)",
            "converged": converged,
            "ik_converged": bool(res.converged),
            "stalled": bool(res.stalled),
            "iterations": res.iterations,
            "wall_time_s": res.wall_time_s,
            "median_iteration_time_s": per_iteration_s,
            "tolerance_m": params.tol_m,
            "tolerance_rad": params.tol_rad,
            "targets": {name: list(xyz) for name, xyz in params.targets},
            "targets_relative": params.relative,
            "com_xy": list(params.com_xy) if params.com_xy is not None else None,
            "residuals": residual_table(res.residuals),
            "plant_residual_m": plant.position_m,
            "plant_residual_rad": plant.orientation_rad,
            "min_joint_limit_margin": min_margin,
            "q": joint_positions_by_name(robot, res.q),
            "model_edits": list(robot.source.edits),
        }
        write_json_atomic(ctx.path("ik_pose.json", "pose"), payload)
        return Outcome(converged, tuple(_summary(robot.name, task_set, params, res, plant, margins,
                                                  converged)),
                       f"every IK and plant (MuJoCo) residual within {params.tol_m:g} m and "
                       f"{params.tol_rad:g} rad")

    return work


def _summary(name: str, task_set: str, params: IKParams, res: IKResult,
             plant: PlantResiduals, margins: dict[str, tuple[float, float]],
             converged: bool) -> list[str]:
    if converged:
        status = "converged"
    elif res.converged:
        status = "NOT converged (the MuJoCo plant disagrees with the IK's model)"
    else:
        status = ("stalled: the step vanished (the target is out of reach, or the start pose is "
                  "singular for it: try another --keyframe)" if res.stalled
                  else "NOT converged (iteration cap)")
    per_it = float(np.median(res.iteration_times_s)) if res.iterations else 0.0
    lines = [f"robot {name} ({task_set} task set, backend {params.backend}): {status} in "
             f"{res.iterations} iterations, {res.wall_time_s * 1e3:.1f} ms ({per_it * 1e6:.0f} "
             f"us/iteration median), solver {params.solver}, tol {params.tol_m:g} m",
             "task residuals (IK's own; plant = measured in MuJoCo):"]
    for task, residual in res.residuals.items():
        text = ", ".join(f"{k.split(' ')[0]} {v:.3e} {k.split(' ')[1].replace('[', '(').replace(']', ')')}"
                         for k, v in residual.as_dict().items())
        plant_text = [f"{plant.position_m[task]:.3e} (m)"] if task in plant.position_m else []
        if task in plant.orientation_rad:
            plant_text.append(f"{plant.orientation_rad[task]:.3e} (rad)")
        if plant_text:
            text += ", plant " + ", ".join(plant_text)
        note = "  (regulariser, not a target)" if residual.regularising else ""
        lines.append(f"  {task:20s} {text}{note}")
    closest = sorted(margins.items(), key=lambda kv: min(kv[1]))[:5]
    if closest:
        lines.append("joint-limit margins (closest 5; to lower, to upper) (rad or m):")
        lines += [f"  {joint:28s} {lo:+.4f} {hi:+.4f}" for joint, (lo, hi) in closest]
    else:
        lines.append("joint-limit margins: no joint has finite position limits")
    worst = max(plant.position_m.values(), default=0.0)
    worst_rad = max(plant.orientation_rad.values(), default=0.0)
    text = (f"plant check: largest residual in MuJoCo {worst:.3e} m "
            f"({'within' if worst <= params.tol_m else 'OUTSIDE'} tol {params.tol_m:g} m)")
    if plant.orientation_rad:
        text += (f", {worst_rad:.3e} rad ({'within' if worst_rad <= params.tol_rad else 'OUTSIDE'} "
                 f"tol {params.tol_rad:g} rad)")
    lines.append(text)
    return lines


#: The ``mbctl ik`` job.
IK = Job("ik", prepare)
