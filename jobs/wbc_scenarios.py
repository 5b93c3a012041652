"""The g1-wbc scenarios: task targets as functions of time, and the pushes on the plant.

``stand``    CoM over the middle of the feet.
``squat``    CoM height ``z0 - A (1 - cos 2 pi f t)``, A = 0.06 m, f = 0.5 Hz.
``one-foot`` CoM over the left sole, right foot released (force ramp), lifted 5 cm, held 5 s,
             put back, CoM back to the middle.
``reach``    both palms 0.20 m forward and back (min-jerk) while balancing.
``push``     a horizontal force on the pelvis held 0.1 s (``impulse`` N s) from 8 directions,
             2 s apart (or one, ``direction`` deg), no stepping.

Each motion is a min-jerk blend (:func:`mbctl.planners.polynomial.minimum_jerk_at`) evaluated at
the control cycle's time.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import mujoco
import numpy as np
import pinocchio as pin

from mbctl.control.tasks import AccelerationGains, FramePoseTask, FramePositionTask
from mbctl.control.wbc import Standing
from mbctl.planners.polynomial import minimum_jerk_at
from mbctl.robots.g1 import FEET, PALM_SITES, PELVIS
from mbctl.robots.interface import RobotState
from mbctl.sim.perturb import Push, PushSchedule

#: CoM drop [m] at the bottom of the squat is twice this. The G1's ankle pitch (range down to
#: -0.873 rad) reaches its limit near 7 cm from the crouched start with flat feet; 6 cm keeps it
#: clear (at 8 cm the ankle ran into MuJoCo's joint limit once per cycle: a contact-force spike).
SQUAT_AMPLITUDE_M = 0.06
SQUAT_FREQUENCY_HZ = 0.5
LIFT_HEIGHT_M = 0.05
REACH_M = 0.20
PUSH_HOLD_S = 0.1
PUSH_PERIOD_S = 2.0

#: Sets the task targets for a time [s] since the start.
Schedule = Callable[[float, RobotState], None]


def sole_center_W(wb: Standing, foot: str) -> np.ndarray:
    """Centre (3,) [m] in W of a foot's contact points at the controller's current state."""
    cs = wb.controller.contacts[foot]
    return wb.controller.state.frame_pose(cs.fid).act(cs.contact.points_F.mean(axis=0))


def scenario(name: str, wb: Standing, model: mujoco.MjModel, impulse_n_s: float = 10.0,
             direction_deg: float | None = None) -> tuple[Schedule, PushSchedule | None]:
    """Set the initial targets of scenario ``name``; return its schedule and its pushes (or None).

    Args:
        name: One of ``stand``, ``squat``, ``one-foot``, ``reach``, ``push``.
        wb: The standing controller, held at the start state (``wb.hold``).
        model: The plant's model (pushes are built on its bodies).
        impulse_n_s: Push impulse [N s] (push).
        direction_deg: Push direction [deg] in the world x-y plane, or None for eight.
    """
    ctrl, s = wb.controller, wb.controller.state
    c0 = s.com().copy()
    mid = 0.5 * (sole_center_W(wb, FEET[0]) + sole_center_W(wb, FEET[1]))
    home = np.array([mid[0], mid[1], c0[2]])
    wb.base.set_target(pin.SE3.Identity())
    if wb.torso is not None:
        wb.torso.set_target(pin.SE3.Identity())
    wb.posture.set_target(s.q.copy())

    def hold_com(t: float, state: RobotState) -> None:
        wb.com.set_target(*minimum_jerk_at(c0, home, t, 0.0, 1.0))

    if name == "squat":
        w, A = 2 * np.pi * SQUAT_FREQUENCY_HZ, SQUAT_AMPLITUDE_M

        hx, hy, hz = home.tolist()

        def squat(t: float, state: RobotState) -> None:
            c, s = math.cos(w * t), math.sin(w * t)
            if t > 1.0:  # over the feet, at rest: down and up by A (1 - cos w t), on plain floats
                wb.com.set_target([hx, hy, hz - A * (1 - c)], [0.0, 0.0, -(A * w * s)],
                                  [0.0, 0.0, -(A * w * w * c)])
                return
            p, v, a = minimum_jerk_at(c0, home, t, 0.0, 1.0)  # x, y over the feet (new arrays)
            p[2] -= A * (1 - c)
            v[2] -= A * w * s
            a[2] -= A * w * w * c
            wb.com.set_target(p, v, a)
        return squat, None
    if name == "one-foot":
        return _one_foot(wb, c0, home), None
    if name == "reach":
        hands = {}
        for site in PALM_SITES:
            task = FramePositionTask(site, ctrl.model, cost=5.0, servo=AccelerationGains(10.0, 1.0))
            p0 = s.frame_pose(task.frame_id).translation.copy()
            task.set_target(p0)
            ctrl.add_task(task)
            wb.extra[site] = task
            hands[site] = (task, p0)

        def reach(t: float, state: RobotState) -> None:
            hold_com(t, state)
            for task, p0 in hands.values():
                p1 = p0 + [REACH_M, 0.0, 0.0]
                task.set_target(*(minimum_jerk_at(p0, p1, t, 1.0, 2.5) if t < 4.0
                                  else minimum_jerk_at(p1, p0, t, 4.5, 2.5)))
        return reach, None
    if name == "push":
        force = impulse_n_s / PUSH_HOLD_S
        angles = [k * 45.0 for k in range(8)] if direction_deg is None else [direction_deg]
        pushes = PushSchedule(model, [
            Push(PELVIS, (force * np.cos(np.radians(a)), force * np.sin(np.radians(a)), 0.0),
                 1.0 + PUSH_PERIOD_S * k, PUSH_HOLD_S) for k, a in enumerate(angles)])
        return hold_com, pushes
    return hold_com, None


def _one_foot(wb: Standing, c0: np.ndarray, home: np.ndarray) -> Schedule:
    """The one-foot schedule (times in s).

    Shift 0-2, release from 2 (force ramp), lift 2.5-3.5, hold to 8.5, lower to 9.5, touch down and
    load, shift back 10-12.
    """
    ctrl, s = wb.controller, wb.controller.state
    left = sole_center_W(wb, FEET[0])
    over_left = np.array([left[0], left[1], c0[2]])
    right = FEET[1]
    swing = FramePoseTask(right, ctrl.model, 10.0, 10.0, servo=AccelerationGains(20.0, 1.0))
    wb.extra["swing"] = swing
    poses: dict[str, pin.SE3] = {}

    def one_foot(t: float, state: RobotState) -> None:
        wb.com.set_target(*(minimum_jerk_at(c0, over_left, t, 0.0, 2.0) if t < 10.0
                            else minimum_jerk_at(over_left, home, t, 10.0, 2.0)))
        if t >= 2.0 and "down" not in poses and ctrl.contacts[right].target_weight > 0:
            ctrl.release(right)
        if ctrl.contact_released(right) and "down" not in poses:
            # the swing task starts where the foot is, at rest: no acceleration jump
            poses["down"] = pin.SE3(s.frame_pose(ctrl.contacts[right].fid))
            swing.set_target(poses["down"])
            ctrl.add_task(swing)
        if swing in ctrl.tasks:
            down = poses["down"].translation
            up = down + [0, 0, LIFT_HEIGHT_M]
            pf, vf, af = (minimum_jerk_at(down, up, t, 2.5, 1.0) if t < 8.5
                          else minimum_jerk_at(up, down, t, 8.5, 1.0))
            swing.set_target(pin.SE3(poses["down"].rotation, pf), vf, af)
            if t >= 9.5:
                ctrl.remove_task(swing)
                ctrl.touch_down(right)
    return one_foot
