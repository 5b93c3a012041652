"""The ``mbctl ik`` job: solve whole-body IK to convergence, check it on the MuJoCo plant.

Task set. The robot that IS the Menagerie G1 (``mbctl.robots.g1.is_menagerie_g1``: loaded by the
registry name "g1", told apart by its recorded origin, never by the file stem) gets the G1 set:
palm sites added at load time, feet held, palm targets, CoM, pelvis orientation, posture. Any
other robot (a user file named g1.xml included) gets the generic set: targets on any of its
MuJoCo sites or bodies, optional CoM, posture, joint limits. Targets are positions, full poses or
poses relative to another frame (:mod:`mbctl.jobs.ik_params`); tasks may be given priority levels
(``--priority``). Both sets run on either backend, ``qp`` (our Pinocchio QP) or ``mink``
(:func:`mbctl.control.ik.make_whole_body_ik`), through the one IK loop.

Start. ``--keyframe``, else the G1's "stand", else the robot's "home" keyframe when it has one,
else the neutral pose; the output says which. A start outside the joint limits is refused, naming
the joint and the margin, unless ``--clip-start`` clips it into them.

Collisions. ``--avoid-collisions`` (the default set: the G1's self-collision set, for other
robots every robot geom against every other, adjacent bodies excluded) and ``--collision-pair
A:B`` put a collision-avoidance limit in the IK (both backends, the same geom pairs). The G1 is
always checked against its default set, other robots against the pairs they avoid (none avoided:
nothing is checked, and ``collision_free`` is null, never true).

Plant check (never a silent wrong answer, :mod:`mbctl.jobs.ik_plant`): every target measured in
MuJoCo at the final pose, and the collision pairs at every configuration the IK visited. The run is
``converged`` only when the IK's residuals AND the plant residuals are within tolerance
(``tol_m``; ``10 * tol_m`` rad for orientations) AND no checked pair came closer than
``--min-distance`` anywhere on the path; otherwise the pose is still written and the run exits 1.
Targets that cannot be reached without collision end at the closest collision-free pose, reported
as not converged.

Outputs: ``ik_pose.json`` (pose by joint, residuals, plant residuals, collisions) and the runner's
``report.json``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin

from mbctl.control.exceptions import IKSetupError
from mbctl.control.ik import (
    JointPositionLimit,
    WholeBodyIK,
    WholeBodyIKConfig,
    make_whole_body_ik,
    mujoco_frame_type,
)
from mbctl.control.tasks import Tolerance
from mbctl.exceptions import unknown_name_message
from mbctl.jobs.ik_params import RAD_PER_M_TOL, SOLVERS, IKParams, TargetSpec
from mbctl.jobs.ik_plant import PlantFrames, PlantResiduals, path_collisions, plant_frames, plant_residuals
from mbctl.jobs.ik_report import Verdict, payload, summary
from mbctl.jobs.runner import Job, Outcome, RunContext, Work
from mbctl.robots.collision import CollisionPair, GeomPairs, resolve_pairs
from mbctl.robots.exceptions import RobotError, UnknownNameError
from mbctl.robots.g1 import (
    FEET,
    KEYFRAME,
    PALM_SITES,
    PELVIS,
    SELF_COLLISION_PAIRS,
    is_menagerie_g1,
    with_palm_sites,
)
from mbctl.robots.model_pair import Robot
from mbctl.robots.registry import load_robot
from mbctl.sim.atomic import write_json_atomic

__all__ = ["IK", "RAD_PER_M_TOL", "SOLVERS", "IKParams", "PlantFrames", "PlantResiduals", "g1_config",
           "generic_config", "plant_frames", "plant_residuals", "prepare", "start_q", "task_set_for"]

#: A start this far [rad or m] outside a joint limit still counts as inside (keyframes on a limit).
LIMIT_SLACK = 1e-9

#: A stalled solve whose closest avoided pair ends within this [m] of the minimum distance was
#: stopped by collision avoidance.
BLOCKED_WITHIN_M = 1e-3


def g1_config(**weights: Any) -> WholeBodyIKConfig:
    """The G1 whole-body task set (mink's humanoid example): feet held, palm targets, CoM, pelvis.

    Args:
        **weights: Overrides of ``WholeBodyIKConfig``'s fields (weights, limits, priorities, ...).
    """
    return WholeBodyIKConfig(held_frames=FEET, target_frames=tuple(PALM_SITES), base_frame=PELVIS,
                             com=True, **weights)


def generic_config(targets: tuple[str, ...], com: bool, **extra: Any) -> WholeBodyIKConfig:
    """The generic task set: targets on ``targets``, optional CoM, posture, limits.

    The target weight (5 per m, as the G1's palms) is 500 times the posture weight, so the
    regulariser's pull leaves well under 0.1 mm of bias on a reachable target near the start.
    Joint limits: positions, a per-joint step of at most 2 rad (or m) per iteration (a trust
    region: without it a step near a singular pose can spin an unlimited joint by tens of
    radians, and the posture regulariser then pulls the solution off its target) and, for a
    floating base, the base speed limits.
    """
    return WholeBodyIKConfig(target_frames=targets, com=com, target_position_cost=5.0,
                             posture_cost=1e-2, damping=1e-6, joint_max_velocity=2.0, **extra)


def collision_sets(params: IKParams,
                   task_set: str) -> tuple[tuple[CollisionPair, ...], tuple[CollisionPair, ...]]:
    """``(avoided, checked)`` named pairs: what the IK avoids and what the plant check measures."""
    if task_set == "g1":
        default = tuple(CollisionPair(a, b) for a, b in SELF_COLLISION_PAIRS)
    else:
        default = (CollisionPair(("robot",), ("robot",)),)
    avoided = (*(default if params.avoid_collisions else ()), *params.pairs)
    checked = avoided or (default if task_set == "g1" else ())
    return avoided, checked


def task_set_for(robot: Robot, params: IKParams) -> tuple[Robot, WholeBodyIKConfig, str]:
    """The robot (palm sites added for the G1), its task set and the set's name ("g1" or "generic").

    Raises:
        IKSetupError: A target frame the task set does not have (the message lists them).
    """
    specs = params.specs
    g1 = is_menagerie_g1(robot)
    if g1:
        robot = with_palm_sites(robot)
        for spec in specs:
            if spec.frame not in PALM_SITES:
                raise IKSetupError(unknown_name_message("G1 IK target frame", spec.frame, PALM_SITES)
                                   + " (the feet are held at their start pose)")
    for spec in specs:
        for frame in (spec.frame, spec.reference):
            if frame is not None:
                mujoco_frame_type(robot, frame)
    avoided, _ = collision_sets(params, "g1" if g1 else "generic")
    extra: dict[str, Any] = {
        "oriented_frames": tuple(s.frame for s in specs if s.quat_wxyz is not None),
        "relative_targets": tuple((s.frame, s.reference) for s in specs if s.reference is not None),
        "com_height": params.com_xy is not None and len(params.com_xy) == 3,
        "priorities": params.priorities,
        "collision_pairs": avoided,
        "min_distance_m": params.min_distance_m,
        "joint_max_velocities": params.max_velocities,
        "damping_cost": params.damping_cost,
    }
    if g1:
        return robot, g1_config(**extra), "g1"
    return robot, generic_config(tuple(s.frame for s in specs), params.com_xy is not None, **extra), "generic"


def start_q(robot: Robot, keyframe: str | None, task_set: str) -> tuple[np.ndarray, str]:
    """Start configuration (nq,) and what it is: ``keyframe``, the G1's "stand", "home", or neutral."""
    if keyframe is not None:
        return robot.keyframe_q(keyframe), f"keyframe {keyframe!r}"
    if task_set == "g1":
        return robot.keyframe_q(KEYFRAME), f"keyframe {KEYFRAME!r}"
    if "home" in robot.keyframes:
        return robot.keyframe_q("home"), "keyframe 'home'"
    return robot.neutral_q(), "the neutral pose (no 'home' keyframe)"


def within_limits(robot: Robot, q: np.ndarray, start: str, clip: bool) -> tuple[np.ndarray, dict[str, float]]:
    """``q`` checked against the joint limits; with ``clip``, clipped into them.

    Returns:
        The start (nq,) and, for each clipped joint, how far it was outside [rad or m].

    Raises:
        IKSetupError: ``q`` is outside a limit and ``clip`` is False (the message names every
            joint outside, its margin and the limit).
    """
    limit = JointPositionLimit(robot.pin_model)
    margins = limit.margins(q)
    outside = {joint: min(lo, hi) for joint, (lo, hi) in margins.items() if min(lo, hi) < -LIMIT_SLACK}
    if not outside:
        return q, {}
    if not clip:
        lines = []
        for joint, margin in outside.items():
            k = limit.joint_names.index(joint)
            lines.append(f"{joint} at {q[limit.idx_q[k]]:.4f} (limits [{limit.q_min[k]:.4f}, "
                         f"{limit.q_max[k]:.4f}], {-margin:.4f} outside)")
        raise IKSetupError(f"the start ({start}) is outside the joint limits: {'; '.join(lines)} (rad or m). "
                           "Give --clip-start to clip it into the limits, or another --keyframe")
    q = q.copy()
    q[limit.idx_q] = np.clip(q[limit.idx_q], limit.q_min, limit.q_max)
    return q, {joint: -margin for joint, margin in outside.items()}


def _set_targets(ik: WholeBodyIK, params: IKParams) -> None:
    start = ik.targets()
    for spec in params.specs:
        target = start[spec.frame]
        position = target.position if spec.position is None else np.array(spec.position, dtype=float)
        if params.relative and spec.position is not None:
            position = position + target.position
        rotation = None if spec.quat_wxyz is None else _rotation(spec)
        ik.set_target_pose(spec.frame, position, rotation)
    if params.com_xy is not None:
        com = np.array(params.com_xy, dtype=float)
        ik.set_com_target(com + ik.com()[:len(com)] if params.relative else com)


def _rotation(spec: TargetSpec) -> np.ndarray:
    w, x, y, z = spec.quat_wxyz or (1.0, 0.0, 0.0, 0.0)
    return pin.Quaternion(w, x, y, z).normalized().toRotationMatrix()


def prepare(params: IKParams, robot: Robot | None = None) -> Work:
    """Load the robot, choose the task set, build the backend and set the targets (no output yet).

    Args:
        params: The job's parameters.
        robot: An already loaded model pair to use instead of loading ``params.robot`` (tests).

    Raises:
        IKSetupError: Unknown target frame or collision name, a start outside the joint limits
            (without ``clip_start``), backend setup failure.
        ToolkitError: The robot cannot be found or loaded.
    """
    if robot is None:
        robot = load_robot(params.robot, params.scene, model_dir=params.model_dir, roots=params.roots)
    try:
        robot, config, task_set = task_set_for(robot, params)
        q0, start = start_q(robot, params.keyframe, task_set)
        checked: GeomPairs | None = None
        _, named = collision_sets(params, task_set)
        if named:
            checked = resolve_pairs(robot, named)
    except (UnknownNameError, RobotError) as exc:
        raise IKSetupError(str(exc)) from None
    q0, clipped = within_limits(robot, q0, start, params.clip_start)
    ik = make_whole_body_ik(params.backend, robot, config, q0, params.solver)
    _set_targets(ik, params)

    def work(ctx: RunContext) -> Outcome:
        res = ik.solve(q0, Tolerance(params.tol_m, params.tol_rad), max_iters=params.max_iters)
        plant = plant_residuals(robot, ik, res.q)
        collisions = path_collisions(robot, checked, res.q_path) if checked is not None else None
        verdict = Verdict.of(res, plant, collisions, params, BLOCKED_WITHIN_M)
        ctx.sections["inputs"] = {"task_set": task_set, "backend": params.backend, "start": start,
                                  "clipped_start": clipped, "model_edits": list(robot.source.edits)}
        margins = ik.position_limit.margins(res.q)
        body = payload(robot, ik, params, task_set, start, clipped, res, plant, collisions, margins, verdict)
        ctx.values.update({key: body[key] for key in (
            "converged", "ik_converged", "iterations", "wall_time_s", "median_iteration_time_s",
            "min_joint_limit_margin", "min_distance_m", "closest_pair", "closest_pair_step",
            "collision_free")})
        ctx.values["max_plant_residual_m"] = max(plant.position_m.values(), default=0.0)
        ctx.values["max_plant_residual_rad"] = max(plant.orientation_rad.values(), default=0.0)
        write_json_atomic(ctx.path("ik_pose.json", "pose"), body)
        lines = summary(robot.name, task_set, start, clipped, params, res, plant, collisions, margins,
                        verdict)
        bound = (f"every IK and plant (MuJoCo) residual within {params.tol_m:g} m and {params.tol_rad:g} rad"
                 + (f", every checked pair >= {params.min_distance_m:g} m apart on the whole path"
                    if collisions is not None else ""))
        return Outcome(verdict.converged, tuple(lines), bound)

    return work


#: The ``mbctl ik`` job.
IK = Job("ik", prepare)
