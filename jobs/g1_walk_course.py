"""A course of waypoints (``mbctl g1-walk course``): the walking command from the pelvis's pose each cycle.

``--waypoints`` gives the course as ``X,Y,YAW;X,Y,YAW;...`` ([m, m, deg] in the world, whose origin
and x axis are the start's) or a file of such lines (one waypoint a line, ``#`` comments); without
it the course is :data:`DEFAULT_COURSE`, 12 waypoints over about 10 m with four 90 deg turns. The
command toward the current waypoint is :class:`~mbctl.planners.WaypointFollower`'s (a proportional
law in the body frame) capped at ``--speed`` (the most forward [m/s], sideways [m/s] and turning
[rad/s]) and clamped by the step limits. A waypoint is reached within :data:`POSITION_TOLERANCE_M`
and :data:`YAW_TOLERANCE_DEG` of where the robot stands (the middle of its feet, their heading: the
pelvis sways from foot to foot); intermediate waypoints are approached at no less than the
smaller speed cap, so the walk does not stop at each.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from mbctl.control.exceptions import WBCSetupError
from mbctl.control.wbc import WalkingController
from mbctl.planners import VelocityCommand, WaypointFollower
from mbctl.robots.commands import Command
from mbctl.robots.conventions import quat_xyzw_yaw
from mbctl.robots.interface import RobotState

#: A course of about 10 m: (x [m], y [m], yaw [deg]).
DEFAULT_COURSE = ((1.0, 0.0, 0.0), (2.0, 0.0, 0.0), (3.0, 0.0, 0.0), (3.5, 0.5, 90.0), (3.5, 1.5, 90.0),
                  (3.0, 2.0, 180.0), (2.0, 2.0, 180.0), (1.0, 2.0, 180.0), (0.5, 1.5, -90.0),
                  (0.5, 0.8, -90.0), (1.0, 0.3, 0.0), (1.5, 0.3, 0.0))
POSITION_TOLERANCE_M = 0.10
YAW_TOLERANCE_DEG = 10.0


def parse_waypoints(text: str | None) -> np.ndarray:
    """Waypoints (K, 3) [m, m, rad] from ``X,Y,YAW_DEG;...`` or a file of such lines (None: the default).

    Raises:
        WBCSetupError: Neither an existing file nor a list of 3 finite numbers per waypoint.
    """
    one_file = text is not None and ";" not in text and Path(text).is_file()
    if text is None:
        rows: list[str] = [f"{x},{y},{yaw}" for x, y, yaw in DEFAULT_COURSE]
    elif one_file:
        try:
            lines = Path(text).read_text().splitlines()
        except (OSError, UnicodeDecodeError) as exc:
            raise WBCSetupError(f"--waypoints: cannot read the file {text!r} ({exc}); give X,Y,YAW;... "
                                "(m, m, deg) or a file of such lines") from None
        rows = [line.split("#")[0].strip() for line in lines]
    else:
        rows = text.split(";")
    # text that looks like a path (a folder in it, a .txt or .csv name) was meant as a file: none is there
    meant_file = text is not None and not one_file and (
        Path(text).name != text or Path(text).suffix.lower() in (".txt", ".csv"))
    no_file = " (and no file of that name)" if meant_file else ""
    points = []
    for row in (r for r in rows if r.strip()):
        try:
            values = [float(v) for v in row.replace(" ", ",").split(",") if v]
        except ValueError:
            values = []
        if len(values) != 3 or not all(math.isfinite(v) for v in values):
            raise WBCSetupError(f"--waypoints must be X,Y,YAW;X,Y,YAW;... (m, m, deg) or a file of such "
                                f"lines; got the waypoint {row!r}{no_file}")
        points.append([values[0], values[1], math.radians(values[2])])
    if not points:
        raise WBCSetupError(f"--waypoints gave no waypoint; got {text!r}")
    return np.array(points)


def pose_of(q: np.ndarray) -> np.ndarray:
    """The base's (x [m], y [m], yaw [rad]) from q (its quaternion (x, y, z, w) in q[3:7])."""
    return np.array([q[0], q[1], quat_xyzw_yaw(q[3:7])])


def capped(command: np.ndarray, caps: VelocityCommand) -> np.ndarray:
    """``command`` (vx, vy, yaw rate) scaled onto the caps' ellipsoid where it is outside.

    The caps bound the axes together, ``(vx / cap_x)^2 + (vy / cap_y)^2 + (wz / cap_w)^2 <= 1``,
    not each alone: a full turn is not combined with full forward and sideways speeds (on the
    default course the G1 fell turning at 0.5 rad/s while stepping at 0.27 m/s forward and 0.18 m/s
    sideways, each within its own cap).
    """
    scale = float(np.linalg.norm(command / np.asarray(caps, dtype=float)))
    return command / scale if scale > 1.0 else command


class CourseWalker:
    """The walker after a course: each cycle the follower's command (capped) from the state's base pose.

    A :class:`~mbctl.control.controller.Controller` for :func:`mbctl.control.loop.run` (reference None).

    Args:
        walker: The walking controller.
        waypoints: (K, 3) [m, m, rad] in W.
        caps: The largest command (forward [m/s], sideways [m/s], turning [rad/s]), each > 0.
    """

    reference_type = None

    def __init__(self, walker: WalkingController, waypoints: np.ndarray, caps: VelocityCommand):
        if not all(c > 0 for c in caps):
            raise WBCSetupError(f"the course's --speed caps must all be > 0 (m/s, m/s, rad/s); got "
                                f"{tuple(caps)}")
        self.walker, self.waypoints, self.caps = walker, waypoints, caps
        self.follower = self._follower()

    def _follower(self) -> WaypointFollower:
        return WaypointFollower(self.waypoints, POSITION_TOLERANCE_M, math.radians(YAW_TOLERANCE_DEG),
                                cruise_m_s=min(self.caps.vx_m_s, self.caps.vy_m_s))

    def pose(self, state: RobotState) -> np.ndarray:
        """Where the robot is: the middle of its feet and their heading (the pelvis sways each step)."""
        gait = self.walker.gait
        if gait is None:
            return pose_of(state.q)
        mid = np.mean([s.position[:2] for s in gait.placed.values()], axis=0)
        return np.array([mid[0], mid[1], gait.heading(state.time_s)])

    def reset(self) -> None:
        """Start the course again (the walker too)."""
        self.follower = self._follower()
        self.walker.reset()

    def compute(self, state: RobotState, reference: object = None) -> Command:
        """The capped command toward the current waypoint, then the walker's torques."""
        command = np.array(self.follower.command(self.pose(state), state.time_s))
        self.walker.set_command(VelocityCommand(*capped(command, self.caps)))
        return self.walker.compute(state)

    def values(self, q_final: np.ndarray) -> dict[str, Any]:
        """The course's report values (the final errors of the pelvis's final pose ``q_final`` too)."""
        f = self.follower
        distance, yaw = f.errors(pose_of(q_final), len(self.waypoints) - 1)
        return {"waypoints": [{"x_m": float(w[0]), "y_m": float(w[1]), "yaw_deg": math.degrees(w[2]),
                               "reached_at_s": None if math.isnan(t) else float(t)}
                              for w, t in zip(self.waypoints, f.reached_at_s, strict=True)],
                "waypoints_reached": int(np.sum(np.isfinite(f.reached_at_s))),
                "waypoints_planned": len(self.waypoints),
                "course_time_s": None if not f.done else float(f.reached_at_s[-1]),
                "final_position_error_m": distance, "final_yaw_error_deg": math.degrees(yaw)}
