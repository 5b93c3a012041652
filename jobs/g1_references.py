"""The G1 jobs' references: the welded G1's tracking waypoints and a ruckig arm trajectory."""

from __future__ import annotations

import numpy as np

from mbctl.planners.ruckig_planner import JointLimits, plan_ruckig
from mbctl.planners.trajectory import JointTrajectory
from mbctl.robots.g1 import KEYFRAME
from mbctl.robots.model_pair import Robot

#: The arm trajectory's (velocity [rad/s], acceleration [rad/s^2], jerk [rad/s^3]) limits.
ARM_LIMITS = (1.5, 6.0, 40.0)


def _set(q: np.ndarray, names: list[str], values: dict[str, float]) -> np.ndarray:
    out = q.copy()
    for k, v in values.items():
        out[names.index(k)] = v
    return out


def track_waypoints(robot: Robot) -> np.ndarray:
    """Waypoints (4, nq) [rad] for the welded G1: start (legs bent, feet clear), A, B, start."""
    names = list(robot.joints)
    q0 = robot.keyframe_q(KEYFRAME)
    legs_bent = {f"{s}_{j}_joint": v for s in ("left", "right")
                 for j, v in (("hip_pitch", -0.3), ("knee", 0.6), ("ankle_pitch", -0.3))}
    start = _set(q0, names, legs_bent)
    a = _set(start, names, {
        "left_hip_pitch_joint": -0.6, "left_knee_joint": 1.0, "left_ankle_pitch_joint": -0.3,
        "right_hip_pitch_joint": -0.3, "right_knee_joint": 0.8, "right_ankle_pitch_joint": -0.4,
        "left_shoulder_pitch_joint": -0.8, "left_shoulder_roll_joint": 0.5, "left_elbow_joint": 0.3,
        "right_shoulder_pitch_joint": 0.4, "right_shoulder_roll_joint": -0.4,
        "right_elbow_joint": 1.2, "left_wrist_roll_joint": 0.5, "right_wrist_pitch_joint": -0.4,
        "waist_yaw_joint": 0.3})
    b = _set(start, names, {
        "left_hip_pitch_joint": -0.5, "left_knee_joint": 0.9, "left_hip_roll_joint": 0.25,
        "right_hip_pitch_joint": -0.2, "right_knee_joint": 0.6, "right_hip_roll_joint": -0.25,
        "left_shoulder_pitch_joint": 0.3, "left_shoulder_yaw_joint": 0.4, "left_elbow_joint": 1.0,
        "right_shoulder_pitch_joint": -0.6, "right_shoulder_yaw_joint": -0.3,
        "right_elbow_joint": 0.5, "left_wrist_yaw_joint": -0.5, "right_wrist_roll_joint": 0.4,
        "waist_yaw_joint": -0.2})
    return np.vstack([start, a, b, start])


def arm_trajectory(robot: Robot, side: str, dt_s: float) -> JointTrajectory:
    """A ruckig trajectory of one arm: keyframe -> raised and bent -> keyframe (7 joints)."""
    names = tuple(f"{side}_{j}_joint" for j in ("shoulder_pitch", "shoulder_roll", "shoulder_yaw",
                                                  "elbow", "wrist_roll", "wrist_pitch", "wrist_yaw"))
    q0 = robot.keyframe_q(KEYFRAME)
    start = np.array([q0[robot.joint(n).idx_q] for n in names])
    s = 1.0 if side == "left" else -1.0
    goal = start + np.array([-0.9, 0.4 * s, 0.3 * s, 0.6, 0.4 * s, -0.3, 0.3 * s])
    limits = JointLimits.uniform(len(names), *ARM_LIMITS)
    there = plan_ruckig(start, goal, limits, dt_s, names)
    back = plan_ruckig(goal, start, limits, dt_s, names)
    return there.then(back)
