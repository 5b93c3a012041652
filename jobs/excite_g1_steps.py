"""The G1 excitation's steps: shift the CoM over one foot, lift the other and put it back, or abort.

A step (phases :data:`STEP_TIMES_S`, from its start): shift the CoM over the other foot's sole;
release the foot (the controller's force ramp); once its contact is free, its swing task
(:class:`~mbctl.jobs.excite_g1_legs.SwingLegs`) holds it where it is, lifts it straight up by
:data:`LIFT_HEIGHT_M` over where it stood (minimum jerk), holds it, lowers it to 2 mm below
where it stood (so the sole lands flat and pressed); put it down (swing task out, constraint back,
force ramp up) when the lowering ends; reload; shift the CoM back.

When the balance watch stops the excitation, no step begins, and the one under way is aborted
toward its safe end: before its foot is released the CoM turns back at once; while the force ramps
out, the foot is loaded again; while it is in the air it is lowered from where it is. The step's
clock then jumps to that phase, and the rest of the step (put down, reload, shift back) runs as
usual.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from mbctl.control.wbc import WholeBodyController
from mbctl.jobs.excite_g1_legs import SwingLegs
from mbctl.planners.polynomial import minimum_jerk_at
from mbctl.robots.interface import RobotState

#: A step's phases [s]: shift the CoM over the other foot, unload, lift, hold, lower, reload, shift back.
STEP_TIMES_S = (1.5, 0.6, 0.8, 1.0, 0.8, 0.6, 1.5)
#: The ends of the phases [s] from the step's start.
MARKS_S = tuple(float(m) for m in np.cumsum(STEP_TIMES_S))
#: Height [m] a foot is lifted to during a step (straight up from where it stood).
LIFT_HEIGHT_M = 0.05
#: How far below where it stood [m] a foot is lowered, so the sole lands flat and pressed.
PRESS_M = 0.002

#: (position, velocity, acceleration) of a smooth step's fraction [-, 1/s, 1/s^2].
Fraction = tuple[float, float, float]


def min_jerk(t: float, duration: float) -> Fraction:
    """The minimum-jerk step ``10 x^3 - 15 x^4 + 6 x^5`` of ``x = t / duration`` (0, 1 outside), its rates.

    The CoM's shift over a foot: its deceleration peaks before the end and is zero there, so the
    CoP overshoots the stance sole's centre less than with a cubic smooth step (whose deceleration
    is largest at the end): the payload excitation's smallest balance margin (then of the CoM's
    projection) went from 7.6 mm to 13.3 mm.
    """
    s, ds, dds = minimum_jerk_at((0.0,), (1.0,), t, 0.0, duration)
    return float(s[0]), float(ds[0]), float(dds[0])


def _inverse_min_jerk(s: float) -> float:
    """The ``x`` in [0, 1] at which :func:`min_jerk` reaches ``s`` (bisection; it is monotonic)."""
    lo, hi = 0.0, 1.0
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if min_jerk(mid, 1.0)[0] < s else (lo, mid)
    return 0.5 * (lo + hi)


@dataclass
class Step:
    """One step and how far it got.

    Attributes:
        foot: The foot that is lifted.
        t0: Its start [s] (the schedule's time).
        skip_s: How far its clock jumped ahead [s] (an aborted step goes to its safe phase).
        released: Its foot's force ramp was started (or its release was skipped).
        landed: Its foot was put down again (or never left).
        aborted: The balance watch's stop cut it short.
        ground: Where the foot stood, X_WF.
        lift_off: Where the foot was when its contact was freed, X_WF.
        lower_from: Where an aborted step's lowering starts: position (3,) [m] and rotation fraction.
    """

    foot: str
    t0: float
    skip_s: float = 0.0
    released: bool = False
    landed: bool = False
    aborted: bool = False
    ground: pin.SE3 | None = None
    lift_off: pin.SE3 | None = None
    lower_from: np.ndarray | None = None

    def tau(self, t: float) -> float:
        """Time [s] into the step at schedule time ``t``."""
        return t - self.t0 + self.skip_s


class Steps:
    """The steps of an excitation, run one at a time; the free foot's target each cycle.

    Args:
        controller: The whole-body controller (its contacts are released and put down).
        model: The controller's model (the feet's poses from the measured state).
        starts: (foot, start [s]) of each step, one after the other.
        legs: The feet's swing tasks and leg IK.

    Attributes:
        steps: The steps.
        free: Each free foot's target this cycle: pose X_WT, linear velocity (3,) [m/s] and
            acceleration (3,) [m/s^2] in W.
    """

    def __init__(self, controller: WholeBodyController, model: pin.Model, starts: list[tuple[str, float]],
                 legs: SwingLegs):
        self.ctrl, self.model, self.data, self.legs = controller, model, model.createData(), legs
        self.steps = [Step(foot, t0) for foot, t0 in starts]
        self.free: dict[str, tuple[pin.SE3, np.ndarray, np.ndarray]] = {}

    def phase(self, t: float, state: RobotState, stopped_at_s: float | None) -> tuple[str, Fraction] | None:
        """(foot, CoM shift fraction and its rates) of the step under way at ``t`` [s], else None.

        Drives the contacts and :attr:`free`; with the excitation stopped at ``stopped_at_s``, no step
        begins and the one under way is aborted (see the module docstring).
        """
        for step in self.steps:
            tau = step.tau(t)
            if not 0.0 <= tau <= MARKS_S[-1] or (stopped_at_s is not None and step.t0 > stopped_at_s):
                continue
            if stopped_at_s is not None and not (step.aborted or step.landed):
                tau = self._abort(step, t, tau)
            return step.foot, self._advance(step, t, tau, state)
        return None

    def _advance(self, step: Step, t: float, tau: float, state: RobotState) -> Fraction:
        ctrl, foot = self.ctrl, step.foot
        if tau < MARKS_S[5]:
            s_shift = min_jerk(tau, STEP_TIMES_S[0])
        else:
            s, ds, dds = min_jerk(tau - MARKS_S[5], STEP_TIMES_S[-1])
            s_shift = (1.0 - s, -ds, -dds)
        if tau >= MARKS_S[0] and not step.released:
            step.ground = pin.SE3(ctrl.contacts[foot].X_WF0)
            ctrl.release(foot)
            step.released = True
        if step.released and not step.landed and ctrl.contact_released(foot):
            if tau >= MARKS_S[4]:
                self.legs.land(ctrl, foot)
                step.landed = True
                self.free.pop(foot, None)
            else:
                if foot not in self.free:  # its swing task starts where the foot is, at rest
                    pin.framesForwardKinematics(self.model, self.data, np.asarray(state.q))
                    step.lift_off = pin.SE3(self.data.oMf[self.model.getFrameId(foot)])
                    self.legs.lift(ctrl, foot, step.lift_off)
                self.free[foot] = self._swing_target(step, tau)
        return s_shift

    def _abort(self, step: Step, t: float, tau: float) -> float:
        """Cut ``step`` short toward its safe end; the step's new time [s] (its clock jumps there)."""
        step.aborted = True
        contact = self.ctrl.contacts[step.foot]
        if not step.released:  # the CoM turns back from where its shift got to
            x = _inverse_min_jerk(1.0 - min_jerk(tau, STEP_TIMES_S[0])[0])
            new_tau = max(tau, MARKS_S[5] + x * STEP_TIMES_S[-1])
            step.released = step.landed = True
        elif contact.active:  # its force is ramping out: load it again
            contact.target_weight = 1.0
            new_tau = max(tau, MARKS_S[4])
            step.landed = True
        elif step.foot in self.free:  # in the air: lowered from its target now (unless already going down)
            if tau < MARKS_S[3]:
                target = self.free[step.foot][0]
                fraction = 1.0 if tau >= MARKS_S[2] else min_jerk(tau - MARKS_S[1], STEP_TIMES_S[2])[0]
                step.lower_from = np.append(target.translation, fraction)
            new_tau = max(tau, MARKS_S[3])
        else:  # freed this cycle, not yet held by its task: put it down from where it is
            new_tau = max(tau, MARKS_S[3])
        step.skip_s += new_tau - tau
        return new_tau

    def _swing_target(self, step: Step, tau: float) -> tuple[pin.SE3, np.ndarray, np.ndarray]:
        """The free foot's target pose, linear velocity [m/s], acceleration [m/s^2] in W, ``tau`` [s] in.

        From where its contact was freed (a lightly loaded foot may have rolled a little on the
        floor) it is lifted by :data:`LIFT_HEIGHT_M` over where it stood, turning back to how it
        stood, held, and lowered to :data:`PRESS_M` below where it stood (minimum jerk each way).
        """
        X0, X1 = step.lift_off, step.ground
        assert X0 is not None and X1 is not None  # noqa: S101 - set when the foot was released and freed
        up = np.append(X1.translation + [0.0, 0.0, LIFT_HEIGHT_M], 1.0)
        down = np.append(X1.translation - [0.0, 0.0, PRESS_M], 1.0)
        if tau < MARKS_S[3]:
            x, dx, ddx = minimum_jerk_at(np.append(X0.translation, 0.0), up, tau, MARKS_S[1], STEP_TIMES_S[2])
        else:
            start = up if step.lower_from is None else step.lower_from
            if step.lower_from is None and step.aborted:  # freed at the abort: lowered from where it is
                start = np.append(X0.translation, 0.0)
            x, dx, ddx = minimum_jerk_at(start, down, tau, MARKS_S[3], STEP_TIMES_S[4])
        R = X0.rotation @ pin.exp3(x[3] * pin.log3(X0.rotation.T @ X1.rotation))
        return pin.SE3(R, x[:3]), dx[:3], ddx[:3]
