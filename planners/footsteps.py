"""Footsteps from a velocity command (changeable every cycle) or from waypoints, within the model's limits.

**Placement.** The feet alternate. With the step period ``T = T_ss + T_ds`` and the clamped
command (vx, vy, wz) [m/s, m/s, rad/s], the next footstep of foot side s (+1 left, -1 right)
is placed from the stance footstep S (x, y, yaw) as

    yaw  = yaw_S + wz T
    p    = p_S + R(yaw_S + wz T / 2) (vx T, s w + s max(0, s vy) 2 T)

so the body advances (vx, vy, wz) T per step on average: every footstep turns the feet by wz T,
each step moves the swing foot vx T ahead of the stance foot, and sideways the foot on the side of
the motion steps out by ``2 |vy| T`` while the other closes to the nominal width w. Each footstep is
then projected into the step limits (:meth:`FootstepPlanner.limit_step`; turning while stepping
can carry it past one), so the width is never below ``w_min`` and the feet never cross.

**Limits derived from the model** (:func:`step_limits_from_model`, the derivation as a formula):

- *Leg reach.* The leg is the chain of joints from the floating base to the foot frame; its
  length L is the distance from the first joint (the hip) to the sole at the neutral
  configuration (straight legs), the sole being ``sole_depth`` below the foot frame. Walking with
  the CoM at ``z_c``, the hip is at ``h = z_c - (z_com - z_hip)`` of the reference (standing)
  configuration; keeping the knee off its straight-leg singularity (at most
  ``MAX_EXTENSION`` L from hip to sole), the foot reaches ``r = sqrt((0.97 L)^2 - h^2)`` in
  front of or behind the hip. In double support the hip is between the feet, so a step (foot to
  foot) is at most ``2 r``; ``REACH_USE`` of it is used (the CoM is not exactly midway at
  touchdown). Backward steps get ``BACKWARD_FRACTION`` of that (the sole extends further in
  front of the ankle than behind: a backward step lands on the short side). Sideways the feet
  spread by at most ``LATERAL_FRACTION`` r beyond the nominal width (each leg, with the hips
  midway, then spans half of it).
- *Foot size.* The nominal width w is the feet's distance in the reference configuration. The
  narrowest stance keeps the soles' inner edges ``CLEARANCE_M`` apart: ``w_min = sole width
  + clearance``.
- *Hip yaw range.* The feet turn by at most ``YAW_FRACTION`` of the smaller hip-yaw range
  (the leg's joint whose axis is vertical at the neutral configuration), and by no more than the
  angle at which the turned foot's toe would reach the clearance of the other sole:
  ``asin((w - w_min) / toe)``, toe the sole's reach in front of the foot frame.
- *Timing* (:class:`GaitTiming`) is the controller's: single support within
  [``MIN_SINGLE_SUPPORT_S``, ``MAX_SINGLE_SUPPORT_S``], double support within
  [``MIN_DOUBLE_SUPPORT_S``, ``MAX_DOUBLE_SUPPORT_S``].

**Clamping.** The command is clamped per axis (forward/backward step, lateral step, yaw), then
(vx, vy) scaled together onto the reach ellipse ``(vx T / step_x)^2 + (2 vy T / step_y)^2 <= 1``;
:class:`CommandClamp` reports the request, what is applied and which limits bound.

**Waypoints** (:class:`WaypointFollower`): (x, y, yaw) goals, one after the other; the command
is a proportional law in the body frame toward the current goal (toward an intermediate one at no
less than a cruise speed, so the walk does not stop at each; facing the way to it while it is more
than ``FACE_WITHIN_M`` ahead, turning to its heading nearer), clamped as above, and the goal counts
as reached within a position and a yaw tolerance. After the last, the law holds it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from mbctl.planners.dcm import convex_hull
from mbctl.planners.exceptions import InvalidLimits, InvalidPlanningInput
from mbctl.robots.model_pair import Robot

#: Largest hip-to-sole distance used, as a fraction of the straight leg's length [-].
MAX_EXTENSION = 0.97
#: Fraction of the geometric step length (2 r) used [-].
REACH_USE = 0.8
#: Backward step length as a fraction of the forward one [-].
BACKWARD_FRACTION = 0.6
#: Outward lateral step as a fraction of the reach r [-].
LATERAL_FRACTION = 1.0
#: Gap [m] kept between the soles' inner edges.
CLEARANCE_M = 0.04
#: Per-step foot rotation as a fraction of the smaller hip-yaw range [-].
YAW_FRACTION = 0.25
#: Timing bounds [s].
MIN_SINGLE_SUPPORT_S, MAX_SINGLE_SUPPORT_S = 0.25, 1.5
MIN_DOUBLE_SUPPORT_S, MAX_DOUBLE_SUPPORT_S = 0.02, 0.5
#: The waypoint follower faces the way to a goal farther than this [m] (and turns to its heading nearer).
FACE_WITHIN_M = 0.3
#: A joint axis counts as vertical when its z component exceeds this [-].
VERTICAL_AXIS = 0.9


class VelocityCommand(NamedTuple):
    """A walking command in the body frame (x forward, y left).

    Attributes:
        vx_m_s: Forward speed [m/s].
        vy_m_s: Leftward speed [m/s].
        yaw_rate_rad_s: Turning rate [rad/s] (positive: to the left).
    """

    vx_m_s: float = 0.0
    vy_m_s: float = 0.0
    yaw_rate_rad_s: float = 0.0


class CommandClamp(NamedTuple):
    """What the limits did to a command.

    Attributes:
        requested: The command as given.
        applied: The command the footsteps follow.
        limited_by: The limits that bound (empty: the command was within them), e.g.
            ``("forward step",)``.
    """

    requested: VelocityCommand
    applied: VelocityCommand
    limited_by: tuple[str, ...]

    @property
    def clamped(self) -> bool:
        """Whether a limit changed the command."""
        return bool(self.limited_by)


class Footstep(NamedTuple):
    """Where a foot is put down: its foot frame's pose, level (roll = pitch = 0).

    Attributes:
        foot: The foot's name (its frame).
        side: +1 for the left foot, -1 for the right.
        position: Foot frame origin (3,) [m] in W.
        yaw_rad: Heading [rad] in W.
    """

    foot: str
    side: int
    position: np.ndarray
    yaw_rad: float

    def point_W(self, p_F: npt.ArrayLike) -> np.ndarray:
        """A point given in the foot frame (3,) [m], in W (the footstep level)."""
        c, s = math.cos(self.yaw_rad), math.sin(self.yaw_rad)
        x, y, z = (p_F.tolist() if isinstance(p_F, np.ndarray) else np.asarray(p_F, dtype=float).tolist())
        o = self.position.tolist()  # plain floats: the same sums, without numpy's per-call cost
        return np.array([o[0] + (c * x - s * y), o[1] + (s * x + c * y), o[2] + z])


@dataclass(frozen=True)
class GaitTiming:
    """Step timing.

    Attributes:
        single_support_s: Time on one foot (the swing) [s].
        double_support_s: Time on both feet between swings [s].
    """

    single_support_s: float = 0.4
    double_support_s: float = 0.1

    def __post_init__(self) -> None:
        for name, lo, hi in (("single_support_s", MIN_SINGLE_SUPPORT_S, MAX_SINGLE_SUPPORT_S),
                             ("double_support_s", MIN_DOUBLE_SUPPORT_S, MAX_DOUBLE_SUPPORT_S)):
            value = getattr(self, name)
            if not (math.isfinite(value) and lo <= value <= hi):
                raise InvalidLimits(f"GaitTiming.{name} = {value!r} s is outside [{lo}, {hi}] s")

    @property
    def step_s(self) -> float:
        """Step period T = T_ss + T_ds [s]."""
        return self.single_support_s + self.double_support_s


@dataclass(frozen=True)
class StepLimits:
    """How far one step may go (relative to the stance foot, in its heading frame).

    Attributes:
        max_forward_m: Longest forward step, foot to foot [m].
        max_backward_m: Longest backward step [m] (positive).
        max_outward_m: Largest lateral step beyond the nominal width [m].
        nominal_width_m: Distance between the feet's frames, sideways [m].
        min_width_m: The narrowest stance [m] (the soles' inner edges a clearance apart).
        max_yaw_rad: Largest rotation of a footstep relative to the previous one [rad].
        sole_xy_m: The sole's outline points (x, y) [m] in the foot frame (empty: the width bound is
            ``min_width_m`` whatever the rotation). With them, a footstep turned relative to the
            stance keeps its whole sole ``min_width_m - sole width`` (the clearance) beyond the
            stance sole's inner edge (:meth:`min_width_for`): a turned toe or heel would otherwise
            reach across at the narrowest stance.
    """

    max_forward_m: float
    max_backward_m: float
    max_outward_m: float
    nominal_width_m: float
    min_width_m: float
    max_yaw_rad: float
    sole_xy_m: tuple[tuple[float, float], ...] = ()

    def __post_init__(self) -> None:
        for name in ("max_forward_m", "max_backward_m", "max_outward_m", "nominal_width_m", "max_yaw_rad"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise InvalidLimits(f"StepLimits.{name} = {value!r} must be finite and > 0")
        if not (math.isfinite(self.min_width_m) and 0 < self.min_width_m <= self.nominal_width_m):
            raise InvalidLimits(f"StepLimits.min_width_m = {self.min_width_m!r} m must be in "
                                f"(0, nominal_width_m = {self.nominal_width_m}] m")
        pts = np.asarray(self.sole_xy_m, dtype=float)
        if self.sole_xy_m and (pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 3
                               or not np.all(np.isfinite(pts))):
            raise InvalidLimits(f"StepLimits.sole_xy_m must be 3 or more finite (x, y) points [m]; got shape "
                                f"{pts.shape}")

    def min_width_for(self, dyaw_rad: float, side: int) -> float:
        """The narrowest width [m] for a footstep turned by ``dyaw_rad`` from the stance, on ``side``.

        ``side`` is the footstep's side of the stance (+1 left, -1 right). In the stance heading
        frame, the turned sole's points are at ``lat + sin(dyaw) x + cos(dyaw) y``; each stays the
        clearance (``min_width_m`` less the sole's width) past the stance sole's inner edge, so a
        line along the stance heading separates the soles. Never below ``min_width_m`` nor above
        the widest step; ``min_width_m`` without ``sole_xy_m``.
        """
        if not self.sole_xy_m:
            return self.min_width_m
        # plain floats over the outline's few points: numpy's per-call cost is larger (called for
        # every previewed footstep, every cycle)
        c, s = math.cos(dyaw_rad), math.sin(dyaw_rad)
        reaches = self._sole_reach
        clearance, reach = reaches[side] if side in reaches else self._reach_toward(side)
        width = clearance + reach - min(side * (s * x + c * y) for x, y in self.sole_xy_m)
        return min(max(width, self.min_width_m), self.nominal_width_m + self.max_outward_m)

    @cached_property
    def _min_width_ceiling(self) -> float:
        """Above min_width_for at any rotation, either side [m]: clearance + reach + the farthest point."""
        farthest = max((math.hypot(x, y) for x, y in self.sole_xy_m), default=-math.inf)  # +1e-9: rounding
        reach = max(c + r for c, r in self._sole_reach.values()) if self.sole_xy_m else 0.0
        return max(self.min_width_m, reach + farthest) + 1e-9

    @cached_property
    def _sole_reach(self) -> dict[int, tuple[float, float]]:
        """Per side (+1, -1): the clearance [m] and the sole's farthest point toward that side [m]."""
        return {side: self._reach_toward(side) for side in (1, -1)}

    def _reach_toward(self, side: float) -> tuple[float, float]:
        ys = [y for _, y in self.sole_xy_m]
        return self.min_width_m - (max(ys) - min(ys)), max(side * y for y in ys)


def leg_chain(robot: Robot, foot_frame: str) -> list[int]:
    """The Pinocchio joint ids from the floating base (excluded) down to ``foot_frame``'s joint.

    Raises:
        InvalidPlanningInput: An unknown frame, or a foot not below a floating base.
    """
    model = robot.pin_model
    if not model.existFrame(foot_frame):
        raise InvalidPlanningInput(f"unknown foot frame {foot_frame!r}")
    j = model.frames[model.getFrameId(foot_frame)].parentJoint
    chain = []
    while j > 0 and model.joints[j].nv == 1:
        chain.append(j)
        j = model.parents[j]
    if j == 0 or not chain:
        raise InvalidPlanningInput(f"foot frame {foot_frame!r} is not on a leg below a floating base")
    return chain[::-1]


def step_limits_from_model(robot: Robot, feet: tuple[str, str], sole_points_F: npt.ArrayLike,
                           reference_q: npt.ArrayLike, com_height_m: float) -> StepLimits:
    """The step limits of a biped (the derivation is in the module docstring).

    Args:
        robot: The robot (its Pinocchio model is read).
        feet: The (left, right) foot frames.
        sole_points_F: The sole's contact points (n, 3) [m] in the foot frame (z: below it).
        reference_q: A standing configuration (nq,) with both soles on the floor (e.g. the
            controller's start): the nominal width and the CoM-to-hip offset come from it.
        com_height_m: The CoM height [m] above the soles while walking.

    Raises:
        InvalidPlanningInput: Unknown frames, a leg without a vertical joint, or a CoM too high
            for the leg to reach anywhere.
    """
    model = robot.pin_model
    data = model.createData()
    pts = np.asarray(sole_points_F, dtype=float)
    depth = float(-pts[:, 2].min())
    chains = [leg_chain(robot, f) for f in feet]
    q0 = pin.neutral(model)
    pin.framesForwardKinematics(model, data, q0)
    pin.computeJointJacobians(model, data, q0)
    lengths, yaw_ranges = [], []
    for foot, chain in zip(feet, chains, strict=True):
        X = data.oMf[model.getFrameId(foot)]
        sole = X.translation - depth * X.rotation[:, 2]
        lengths.append(float(np.linalg.norm(sole - data.oMi[chain[0]].translation)))
        yaw = [j for j in chain if abs(pin.getJointJacobian(model, data, j, pin.WORLD)
                                       [5, model.joints[j].idx_v]) > VERTICAL_AXIS]
        if not yaw:
            raise InvalidPlanningInput(f"the leg of {foot!r} has no joint with a vertical axis (hip yaw)")
        iq = model.joints[yaw[0]].idx_q
        yaw_ranges.append(min(-model.lowerPositionLimit[iq], model.upperPositionLimit[iq]))
    q = np.asarray(reference_q, dtype=float)
    pin.framesForwardKinematics(model, data, q)
    com = pin.centerOfMass(model, data, q)
    soles = [data.oMf[model.getFrameId(f)].translation - depth * data.oMf[model.getFrameId(f)].rotation[:, 2]
             for f in feet]
    floor = 0.5 * (soles[0][2] + soles[1][2])
    hip_below_com = com[2] - np.mean([data.oMi[c[0]].translation[2] for c in chains])
    h = com_height_m - hip_below_com
    leg = MAX_EXTENSION * min(lengths)
    if not (0 < h < leg):
        raise InvalidPlanningInput(
            f"CoM height {com_height_m} m puts the hips {h:.3f} m above the soles; the legs reach "
            f"{leg:.3f} m ({MAX_EXTENSION:g} of {min(lengths):.3f} m): lower the CoM (standing CoM "
            f"height {com[2] - floor:.3f} m)")
    reach = math.sqrt(leg**2 - h**2)
    F = pin.SE3(data.oMf[model.getFrameId(feet[1])]).actInv(data.oMf[model.getFrameId(feet[0])])
    width = float(abs(F.translation[1]))
    sole_width = float(pts[:, 1].max() - pts[:, 1].min())
    min_width = min(width, sole_width + CLEARANCE_M)
    toe = float(pts[:, 0].max())
    geometric = math.asin(min(1.0, (width - min_width) / toe)) if toe > 0 else math.pi / 2
    forward = REACH_USE * 2.0 * reach
    max_yaw = YAW_FRACTION * float(min(yaw_ranges))
    if geometric > 0:
        max_yaw = min(max_yaw, geometric)
    return StepLimits(forward, BACKWARD_FRACTION * forward, LATERAL_FRACTION * reach, width, min_width,
                      max_yaw, tuple((float(x), float(y)) for x, y in convex_hull(pts[:, :2])))


class FootstepPlanner:
    """Footsteps from a velocity command within :class:`StepLimits` and :class:`GaitTiming`.

    Args:
        limits: The step limits.
        timing: The step timing.
        feet: The (left, right) foot names.
    """

    def __init__(self, limits: StepLimits, timing: GaitTiming, feet: tuple[str, str]):
        self.limits, self.timing, self.feet = limits, timing, tuple(feet)

    def clamp(self, command: VelocityCommand | tuple[float, float, float]) -> CommandClamp:
        """The command within the limits, and what bound.

        Raises:
            InvalidPlanningInput: A non-finite command.
        """
        req = VelocityCommand(*(float(c) for c in command))
        if not all(math.isfinite(c) for c in req):
            raise InvalidPlanningInput(f"the velocity command must be finite (m/s, m/s, rad/s); got "
                                       f"{tuple(req)}")
        T, lim = self.timing.step_s, self.limits
        limited = []
        vx, vy, wz = req
        x_max = (lim.max_forward_m if vx >= 0 else lim.max_backward_m) / T
        if abs(vx) > x_max:
            vx = math.copysign(x_max, vx)
            limited.append("forward step" if vx > 0 else "backward step")
        y_max = lim.max_outward_m / (2.0 * T)
        if abs(vy) > y_max:
            vy = math.copysign(y_max, vy)
            limited.append("lateral step")
        w_max = lim.max_yaw_rad / T
        if abs(wz) > w_max:
            wz = math.copysign(w_max, wz)
            limited.append("yaw per step")
        ellipse = math.hypot(vx / x_max, vy / y_max)
        if ellipse > 1.0 + 1e-12:
            vx, vy = vx / ellipse, vy / ellipse
            limited.append("reach (forward and lateral together)")
        return CommandClamp(req, VelocityCommand(vx, vy, wz), tuple(limited))

    def next_footstep(self, stance: Footstep, command: VelocityCommand) -> Footstep:
        """The other foot's next footstep from ``stance`` under a (clamped) command, within the limits."""
        T, w = self.timing.step_s, self.limits.nominal_width_m
        vx, vy, wz = command
        s = -stance.side
        dyaw = wz * T
        mid = stance.yaw_rad + 0.5 * dyaw
        dx, dy = vx * T, s * w + s * max(0.0, s * vy) * 2.0 * T
        c, sn = math.cos(mid), math.sin(mid)
        o = stance.position.tolist()
        p = [o[0] + (c * dx - sn * dy), o[1] + (sn * dx + c * dy), o[2] + 0.0]
        foot = self.feet[0] if s > 0 else self.feet[1]
        # turning while stepping can carry it past a limit
        return self._limited(stance, o, foot, s, p, stance.yaw_rad + dyaw)[0]

    def limit_step(self, stance: Footstep, step: Footstep) -> tuple[Footstep, bool]:
        """``step`` moved into the limits relative to ``stance`` (in the stance heading frame).

        The nearest footstep (the exact projection onto the box of the limits) with the forward
        step in [-max_backward, max_forward], the rotation within +-max_yaw and the width (toward
        the step's side) in [min_width, nominal_width + max_outward], min_width that of the
        rotation (:meth:`StepLimits.min_width_for`: the soles never overlap).

        Returns:
            The footstep within the limits, and whether it moved.
        """
        return self._limited(stance, stance.position.tolist(), step.foot, step.side, step.position.tolist(),
                             step.yaw_rad, step)

    def _limited(self, stance: Footstep, o: list[float], foot: str, side: int, position: list[float],
                 yaw_rad: float, step: Footstep | None = None) -> tuple[Footstep, bool]:
        """:meth:`limit_step` on plain floats (``o``: the stance position; ``step``: the footstep if made)."""
        lim = self.limits
        c, sn = math.cos(stance.yaw_rad), math.sin(stance.yaw_rad)
        d = (position[0] - o[0], position[1] - o[1], position[2] - o[2])
        fwd, lat = c * d[0] + sn * d[1], -sn * d[0] + c * d[1]
        width = side * lat
        dyaw = math.remainder(yaw_rad - stance.yaw_rad, 2.0 * math.pi)
        fwd_c = min(max(fwd, -lim.max_backward_m), lim.max_forward_m)
        dyaw_c = min(max(dyaw, -lim.max_yaw_rad), lim.max_yaw_rad)
        widest = lim.nominal_width_m + lim.max_outward_m
        wide = width > lim._min_width_ceiling and side in (1, -1)
        floor = width if wide else lim.min_width_for(dyaw_c, side)
        width_c = min(max(width, floor), widest)  # (most steps are wider than any rotation needs)
        if (fwd_c, width_c, dyaw_c) == (fwd, width, dyaw):
            return (step or Footstep(foot, side, np.array(position), yaw_rad)), False
        lat_c = side * width_c
        p = np.array([o[0] + (c * fwd_c - sn * lat_c), o[1] + (sn * fwd_c + c * lat_c), o[2] + d[2]])
        return Footstep(foot, side, p, stance.yaw_rad + dyaw_c), True

    def plan(self, stance: Footstep, command: VelocityCommand, n: int) -> list[Footstep]:
        """The next ``n`` footsteps from ``stance`` (alternating feet) under a clamped command."""
        steps, current = [], stance
        for _ in range(n):
            current = self.next_footstep(current, command)
            steps.append(current)
        return steps


class WaypointFollower:
    """A velocity command toward (x, y, yaw) waypoints, one after the other.

    Args:
        waypoints: (K, 3) [m, m, rad] in W.
        position_tolerance_m: A waypoint is reached within this distance [m] ...
        yaw_tolerance_rad: ... and this heading error [rad].
        gain_1_s: Proportional gain [1/s] from the pose error to the command.
        cruise_m_s: The least speed [m/s] toward a waypoint that is not the last (0: stop at each).

    Raises:
        InvalidPlanningInput: Not a finite (K, 3) array with K >= 1, or non-positive tolerances.
    """

    def __init__(self, waypoints: npt.ArrayLike, position_tolerance_m: float = 0.05,
                 yaw_tolerance_rad: float = math.radians(5.0), gain_1_s: float = 1.0,
                 cruise_m_s: float = 0.0):
        wps = np.array(waypoints, dtype=float)
        if wps.ndim != 2 or wps.shape[1] != 3 or len(wps) < 1 or not np.all(np.isfinite(wps)):
            raise InvalidPlanningInput(f"waypoints must be a finite (K, 3) array of x [m], y [m], yaw [rad]; "
                                       f"got shape {wps.shape}")
        if not (position_tolerance_m > 0 and yaw_tolerance_rad > 0 and gain_1_s > 0 and cruise_m_s >= 0):
            raise InvalidPlanningInput("the tolerances and the gain must be > 0 and the cruise speed >= 0; "
                                       f"got {position_tolerance_m}, {yaw_tolerance_rad}, {gain_1_s}, "
                                       f"{cruise_m_s}")
        self.waypoints = wps
        self.position_tolerance_m, self.yaw_tolerance_rad = position_tolerance_m, yaw_tolerance_rad
        self.gain_1_s, self.cruise_m_s = gain_1_s, cruise_m_s
        self.index = 0
        #: The time each waypoint was first reached [s] (NaN until then).
        self.reached_at_s = np.full(len(wps), np.nan)

    @property
    def done(self) -> bool:
        """Every waypoint has been reached."""
        return self.index >= len(self.waypoints)

    def errors(self, pose: npt.ArrayLike, index: int | None = None) -> tuple[float, float]:
        """Distance [m] and absolute heading error [rad] from ``pose`` (x, y, yaw) to a waypoint."""
        x, y, yaw = (float(v) for v in np.asarray(pose, dtype=float))
        gx, gy, gyaw = self.waypoints[min(self.index if index is None else index, len(self.waypoints) - 1)]
        return math.hypot(gx - x, gy - y), abs(math.remainder(gyaw - yaw, 2 * math.pi))

    def command(self, pose: npt.ArrayLike, t_s: float) -> VelocityCommand:
        """The command at body pose (x, y, yaw) [m, m, rad] in W at time ``t_s`` [s].

        Once every waypoint is reached it holds the last one (the same law toward it), so a walk
        stops on it rather than wherever its deceleration ends, and steps back to it after a drift.
        """
        while not self.done:
            d, dyaw = self.errors(pose)
            if d > self.position_tolerance_m or dyaw > self.yaw_tolerance_rad:
                break
            self.reached_at_s[self.index] = t_s
            self.index += 1
        x, y, yaw = (float(v) for v in np.asarray(pose, dtype=float))
        gx, gy, gyaw = self.waypoints[min(self.index, len(self.waypoints) - 1)]
        c, s = math.cos(yaw), math.sin(yaw)
        ex, ey = c * (gx - x) + s * (gy - y), -s * (gx - x) + c * (gy - y)
        k = self.gain_1_s
        vx, vy = k * ex, k * ey
        speed = math.hypot(vx, vy)
        if self.index < len(self.waypoints) - 1 and 0 < speed < self.cruise_m_s:
            vx, vy = vx * self.cruise_m_s / speed, vy * self.cruise_m_s / speed
        # far from the goal: face the way to it (walking forward is a biped's best gait), slowing while
        # turning; near it (within FACE_WITHIN_M): turn to its heading
        bearing = math.atan2(ey, ex)
        if math.hypot(ex, ey) > FACE_WITHIN_M and abs(bearing) < math.pi / 2:
            return VelocityCommand(vx * max(math.cos(bearing), 0.0), vy * 0.5, k * bearing)
        return VelocityCommand(vx, vy, k * math.remainder(gyaw - yaw, 2 * math.pi))
