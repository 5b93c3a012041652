"""Where a walk went: the pelvis's displacement and turn against the command, and its path's length.

The turn is unwrapped along the loop's logged path (a course turns a full circle and more); the
command's integral is a measure only for a constant command (a course's is its follower's, new each
cycle: null there).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from mbctl.planners import VelocityCommand
from mbctl.robots.conventions import quat_xyzw_yaw


def commanded_path(t: np.ndarray, command: VelocityCommand, yaw0: float) -> tuple[np.ndarray, float]:
    """The command integrated over times ``t`` (k,) [s]: the displacement (2,) [m] in W and the turn [rad]."""
    dt = np.diff(t, prepend=t[0])
    yaw = yaw0 + command.yaw_rate_rad_s * (t - t[0])
    c, s = np.cos(yaw), np.sin(yaw)
    d = np.array([np.sum((c * command.vx_m_s - s * command.vy_m_s) * dt),
                  np.sum((s * command.vx_m_s + c * command.vy_m_s) * dt)])
    return d, float(yaw[-1] - yaw0)


def path_length(t_s: np.ndarray, q: np.ndarray, period_s: float) -> float:
    """The base's path length [m] in the floor plane, sampled once per ``period_s`` (a gait cycle).

    Sampled at the same phase of each gait cycle (two steps), the sway from foot to foot cancels;
    the run's last state closes the path.
    """
    if len(t_s) < 2:
        return 0.0
    at = np.arange(t_s[0], t_s[-1], period_s)
    rows = np.unique(np.append(np.searchsorted(t_s, at), len(t_s) - 1))
    return float(np.linalg.norm(np.diff(q[rows, :2], axis=0), axis=1).sum())


def turn_along(q_path: np.ndarray) -> float:
    """The base's turn [rad] along configurations (rows, nq) in Pinocchio's order, unwrapped row to row."""
    if len(q_path) < 2:
        return 0.0
    yaw = np.unwrap(quat_xyzw_yaw(q_path[:, 3:7]))
    return float(yaw[-1] - yaw[0])


def displacement_values(q0: np.ndarray, q1: np.ndarray, t: np.ndarray, command: VelocityCommand | None,
                        q_path: np.ndarray) -> dict[str, Any]:
    """The pelvis's displacement and turn, against the command's (None: a course, whose command is not one).

    The turn is ``q0`` to ``q1``, unwrapped by the turn along the loop's logged path ``q_path``.
    """
    d = q1[:2] - q0[:2]
    along = turn_along(q_path)
    yaw0, yaw1 = float(quat_xyzw_yaw(q0[3:7])), float(quat_xyzw_yaw(q1[3:7]))
    turned = math.remainder(yaw1 - yaw0 - along, 2 * math.pi) + along
    duration = float(t[-1] - t[0]) if len(t) > 1 else 0.0
    values = {
        "distance_m": float(np.linalg.norm(d)),
        "mean_speed_m_s": float(np.linalg.norm(d)) / duration if duration > 0 else None,
        "displacement_m": d.tolist(), "yaw_rad": turned,
        "commanded_displacement_m": None, "displacement_fraction": None,
        "commanded_yaw_rad": None, "yaw_fraction": None,
    }
    if command is None:
        return values
    cmd, cmd_yaw = commanded_path(t, command, yaw0)
    length = float(np.linalg.norm(cmd))
    return values | {
        "commanded_displacement_m": cmd.tolist(),
        "displacement_fraction": float(d @ cmd) / length**2 if length > 1e-9 else None,
        "commanded_yaw_rad": cmd_yaw,
        "yaw_fraction": turned / cmd_yaw if abs(cmd_yaw) > 1e-9 else None,
    }
