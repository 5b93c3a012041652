"""The gait's phases of :class:`~mbctl.control.wbc.walking.WalkingController`: start, single, double support.

Phases and their switches (t: the state's time)::

    start  (both feet, start_s)  --release the first swing foot at end - ramp_s-->
    single (one foot, T_ss)      --touchdown: detected, or forced after a late descent-->
    double (both feet, T_ds)     --release the trailing foot at end - ramp_s--> single ...

A released foot is free once its force ramp reaches zero (the QP drops its constraint); the
single support, and the swing path from where the foot is then, start at that cycle. A touchdown
constrains the foot where it is (its force ramping up) and records the footstep it made. The
double support is timed from the planned touchdown when the foot lands early (the DCM plan's
clock does not jump), from the actual one when it lands late.

Each phase gives the DCM plan its start (``Gait.plan_start``): the VRPs in force now, the
next switch time, and in the start phase the initial DCM at rest.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from mbctl.control.wbc.controller import WholeBodyController
from mbctl.control.wbc.walking_config import WalkingConfig
from mbctl.planners.footsteps import Footstep, FootstepPlanner, VelocityCommand
from mbctl.planners.polynomial import minimum_jerk_at
from mbctl.planners.swing import SwingSample, SwingTrajectory

#: The phases.
START, SINGLE, DOUBLE = "start", "single", "double"

#: A touchdown within this of the planned time [s] is on time.
ON_TIME_S = 1e-3


class GaitEvent(NamedTuple):
    """A contact event.

    Attributes:
        kind: "release" (a foot's force starts ramping down), "lift-off" (the foot is free, its
            swing starts) or "touchdown".
        foot: The foot's name.
        time_s: When [s].
        timing: For a touchdown: "early", "on time", "late" or "forced" (no contact was
            detected: the foot was put down at the end of its late descent); else None.
    """

    kind: str
    foot: str
    time_s: float
    timing: str | None = None


@dataclass
class Swing:
    """The single support under way.

    Attributes:
        foot: The swinging foot.
        stance: The supporting foot.
        path: The swing foot's path.
    """

    foot: str
    stance: str
    path: SwingTrajectory

    def footstep(self, side: int) -> Footstep:
        """Where the foot is headed (the path's footstep; ``side`` +1 left, -1 right)."""
        return Footstep(self.foot, side, self.path.target_position.copy(), self.path.target_yaw_rad)


def foot_yaw(X_WF: pin.SE3) -> float:
    """The heading [rad] of a frame's x axis in the world's x-y plane."""
    R = X_WF.rotation
    return math.atan2(R[1, 0], R[0, 0])


def mean_angle(a: float, b: float) -> float:
    """The angle midway between ``a`` and ``b`` [rad] (the short way)."""
    return a + 0.5 * math.remainder(b - a, 2.0 * math.pi)


class Gait:
    """The phase machine of one walk (see the module docstring).

    Args:
        wbc: The whole-body QP (its feet's contacts are released and put down here).
        planner: The footstep planner (its ``feet`` are the (left, right) feet).
        config: The walking options.
        sole_centre_F: The sole centre (3,) [m] in the foot frame (a footstep's VRP).
        poses: Each foot's pose X_WF at the start (both on the ground).
        t0_s: Start time [s].
        com: The CoM (3,) [m] at the start.

    Attributes:
        phase: START, SINGLE or DOUBLE.
        placed: The last footstep of each foot (where it stands or last stood).
        ground_z: The ground's height [m] (the soles' at the start).
        swing: The single support under way (None in the other phases).
        steps: Touchdowns so far.
        touchdowns: Touchdown counts by timing ("early", "on time", "late", "forced").
        events: Every contact event so far.
    """

    def __init__(self, wbc: WholeBodyController, planner: FootstepPlanner, config: WalkingConfig,
                 sole_centre_F: np.ndarray, poses: dict[str, pin.SE3], t0_s: float, com: np.ndarray):
        self.wbc, self.planner, self.config = wbc, planner, config
        self.feet = planner.feet
        self.sole_centre_F = sole_centre_F
        self._sole_xy = (float(sole_centre_F[0]), float(sole_centre_F[1]))
        self.placed = {f: self.footstep(f, X) for f, X in poses.items()}
        self.ground_z = float(np.mean([s.point_W(sole_centre_F)[2] for s in self.placed.values()]))
        self.t0_s = t0_s
        self._com0 = np.array(com, dtype=float)
        self._z_walk = self.ground_z + config.com_height_m
        self._height_after: tuple[float, float, float] | None = None
        self._placed_vrps: dict[str, tuple[Footstep, np.ndarray]] = {}
        self.phase = START
        self.t_phase = t0_s
        self.phase_end = t0_s + config.start_s
        self.swing: Swing | None = None
        self.leading: str | None = None  # in double support: the foot that landed
        self.releasing: str | None = None
        self.steps = 0
        self.touchdowns = {"early": 0, "on time": 0, "late": 0, "forced": 0}
        self.events: list[GaitEvent] = []
        #: Counts the changes of the footsteps (placed, swung to) and phases: equal revisions plan alike.
        self.revision = 0

    def footstep(self, foot: str, X_WF: pin.SE3) -> Footstep:
        """The footstep a foot at pose ``X_WF`` makes."""
        return Footstep(foot, 1 if foot == self.feet[0] else -1, X_WF.translation.copy(), foot_yaw(X_WF))

    def _placed_vrp(self, foot: str) -> np.ndarray:
        """The VRP of ``foot``'s placed footstep (computed once per footstep placed)."""
        step = self.placed[foot]
        cached = self._placed_vrps.get(foot)
        if cached is None or cached[0] is not step:
            cached = self._placed_vrps[foot] = (step, self.vrp(step))
        return cached[1].copy()

    def vrp(self, step: Footstep) -> np.ndarray:
        """A footstep's VRP: its sole centre (2,) [m] in W."""
        x, y = self._sole_xy  # step.point_W(sole_centre_F)[:2], on plain floats
        c, s = math.cos(step.yaw_rad), math.sin(step.yaw_rad)
        o = step.position.tolist()
        return np.array([o[0] + (c * x - s * y), o[1] + (s * x + c * y)])

    @property
    def stance_name(self) -> str:
        """The supporting foot, or "both"."""
        return self.swing.stance if self.swing is not None else "both"

    def _other(self, foot: str) -> str:
        return self.feet[1] if foot == self.feet[0] else self.feet[0]

    def _first_swing(self, command: VelocityCommand) -> str:
        """The foot that swings first: on the side of a sideways or turning command (left by default)."""
        side = command.vy_m_s if command.vy_m_s != 0 else command.yaw_rate_rad_s
        return self.feet[1] if side < 0 else self.feet[0]

    def advance(self, t: float, poses: dict[str, pin.SE3], command: VelocityCommand,
                touching: Callable[[str], bool]) -> GaitEvent | None:
        """Move the phase on at time ``t`` (feet at ``poses``); returns the event of this cycle, if any."""
        if self.swing is not None:
            return self._land(t, self.swing, poses, touching)
        event = None
        if self.releasing is None and t >= self.phase_end - self.config.ramp_s - 1e-9:
            foot = self._first_swing(command) if self.leading is None else self._other(self.leading)
            self.wbc.release(foot)
            self.releasing = foot
            event = self._event(GaitEvent("release", foot, t))
        if self.releasing is not None and self.wbc.contact_released(self.releasing):
            event = self._lift_off(t, self.releasing, poses, command)
        return event

    def _event(self, event: GaitEvent) -> GaitEvent:
        self.events.append(event)
        self.revision += 1
        return event

    def _lift_off(self, t: float, foot: str, poses: dict[str, pin.SE3],
                  command: VelocityCommand) -> GaitEvent:
        cfg = self.config
        stance = self._other(foot)
        target = self.planner.next_footstep(self.placed[stance], command)
        X = poses[foot]
        land = target.position - [0.0, 0.0, cfg.landing_depth_m]  # contact on time despite tracking lag
        path = SwingTrajectory(X.translation, foot_yaw(X), land, target.yaw_rad, cfg.timing.single_support_s,
                               cfg.lift_height_m, t, cfg.swing_horizontal_fraction)
        self.swing = Swing(foot, stance, path)
        self.releasing, self.leading = None, None
        self.phase, self.t_phase, self.phase_end = SINGLE, t, t + cfg.timing.single_support_s
        return self._event(GaitEvent("lift-off", foot, t))

    def _land(self, t: float, swing: Swing, poses: dict[str, pin.SE3],
              touching: Callable[[str], bool]) -> GaitEvent | None:
        """Touch down on contact (after ``early_touchdown_phase`` of the swing), or as a late descent ends."""
        cfg = self.config
        late_s = t - self.phase_end
        contact = t - self.t_phase >= cfg.early_touchdown_phase * swing.path.duration_s \
            and touching(swing.foot)
        if not (contact or late_s * cfg.late_descent_m_s >= cfg.late_extension_m):
            return None
        timing = ("forced" if not contact else "early" if late_s < -ON_TIME_S
                  else "late" if late_s > ON_TIME_S else "on time")
        self.touchdowns[timing] += 1
        self.wbc.touch_down(swing.foot)
        self.placed[swing.foot] = self.footstep(swing.foot, poses[swing.foot])
        self.steps += 1
        self.swing, self.leading = None, swing.foot
        # an early touchdown keeps the plan's clock: double support from the planned touchdown
        start = max(t, self.phase_end)
        self.phase, self.t_phase, self.phase_end = DOUBLE, start, start + cfg.timing.double_support_s
        return self._event(GaitEvent("touchdown", swing.foot, t, timing))

    def retargetable(self, t: float, pushed: bool = False) -> bool:
        """Whether the swing footstep may still move (single support, before ``retarget_until_phase``).

        Args:
            t: Now [s].
            pushed: The DCM is off its plan (a push): before ``pushed_retarget_until_phase`` instead.
        """
        swing = self.swing
        cfg = self.config
        phase = cfg.pushed_retarget_until_phase if pushed else cfg.retarget_until_phase
        until = phase * swing.path.duration_s if swing is not None else 0.0
        return swing is not None and t - self.t_phase < until

    def retarget(self, t: float, step: Footstep) -> None:
        """Move the swing footstep to ``step`` (x, y, yaw; the landing height stays)."""
        if self.swing is not None and self.swing.path.retarget(t, step.position, step.yaw_rad):
            self.revision += 1

    def retime(self, t: float, end_s: float) -> None:
        """Touch the swing foot down at ``end_s`` [s] instead (its path re-timed to reach its footstep)."""
        swing = self.swing
        if swing is not None and swing.path.retime(t, end_s - self.t_phase):
            self.phase_end = self.t_phase + swing.path.duration_s
            self.revision += 1

    def hurry(self, t: float) -> None:
        """In double support after a touchdown: release the trailing foot at ``t`` (the next step sooner).

        The double support then ends ``ramp_s`` from now, the landing foot's force ramp and the
        trailing foot's overlapping; nothing changes in the other phases or once the release started.
        """
        if self.phase == DOUBLE and self.leading is not None and self.releasing is None:
            end = t + self.config.ramp_s
            if end < self.phase_end:
                self.phase_end = end
                self.revision += 1

    def swing_nominal_end_s(self) -> float:
        """The touchdown time [s] the swing under way was planned with (before any re-timing)."""
        return self.t_phase + self.config.timing.single_support_s

    def swing_sample(self, foot: str, t: float) -> SwingSample | None:
        """The swing foot's reference at ``t`` (lowered further while late); None for a foot not swinging."""
        if self.swing is None or foot != self.swing.foot:
            return None
        sample = self.swing.path.at(t)
        late_s = t - self.phase_end
        if late_s > 0:
            cfg = self.config
            drop = min(late_s * cfg.late_descent_m_s, cfg.late_extension_m)
            sample.position[2] -= drop
            if drop < cfg.late_extension_m:
                sample.velocity[2] = -cfg.late_descent_m_s
        return sample

    def plan_start(self, t: float, alpha: float, command: VelocityCommand
                   ) -> tuple[Footstep | None, list[np.ndarray], float, Footstep,
                              tuple[float, np.ndarray, np.ndarray] | None]:
        """What the DCM plan starts from at ``t``.

        Returns:
            ``(first, vrps, t1, stance, initial)``: the footstep being swung to (None in double
            support), the VRPs in force before it, the time of the first switch [s], the footstep
            the preview continues from, and the initial DCM state (start phase only).
        """
        t1 = self.first_switch_s(t, alpha)
        if self.swing is not None:
            first = self.swing.footstep(1 if self.swing.foot == self.feet[0] else -1)
            return first, [self._placed_vrp(self.swing.stance)], t1, first, None
        if self.leading is not None:
            lead = self.placed[self.leading]
            vrps = [self._placed_vrp(self._other(self.leading)), self._placed_vrp(self.leading)]
            return None, vrps, t1, lead, None
        foot = self._other(self.releasing or self._first_swing(command))
        stance = self.placed[foot]
        first = self.planner.next_footstep(stance, command)
        xi0 = self._com0[:2].copy()
        return first, [xi0, self._placed_vrp(foot)], t1, first, (self.t0_s, xi0, np.zeros(2))

    def first_switch_s(self, t: float, alpha: float) -> float:
        """The DCM plan's first switch [s] at ``t`` (``plan_start``'s ``t1``)."""
        T_ds = self.config.timing.double_support_s
        if self.swing is not None:
            return max(self.phase_end, t) + alpha * T_ds
        if self.leading is not None:
            return self.t_phase + alpha * T_ds
        return self.phase_end - (1.0 - alpha) * T_ds

    def height(self, t: float) -> tuple[float, float, float]:
        """CoM height reference [m], its rate [m/s] and acceleration [m/s^2] at ``t``."""
        T = self.config.start_s
        after = t > self.t0_s + T and (t - self.t0_s) / T >= 1.0  # the blend's end: the same at any such t
        if after and self._height_after is not None:
            return self._height_after
        p, v, a = minimum_jerk_at([self._com0[2]], [self._z_walk], t, self.t0_s, T)
        height = float(p[0]), float(v[0]), float(a[0])
        if after:
            self._height_after = height
        return height

    def heading(self, t: float) -> float:
        """The base's heading [rad]: midway between the feet (the swing foot's reference while it swings)."""
        if self.swing is not None:
            return mean_angle(self.placed[self.swing.stance].yaw_rad, self.swing.path.yaw_at(t))
        left, right = (self.placed[f].yaw_rad for f in self.feet)
        return mean_angle(left, right)
