"""The G1 excitation's task references over time: CoM sway and squat, pelvis rocking, the upper body, steps.

:class:`Schedule` sets, each control cycle, the targets of the standing whole-body controller's
tasks (:func:`mbctl.jobs.g1_wbc.g1_whole_body`) from the time and the measured state:

* the CoM squats and sways at incommensurate frequencies (:data:`COM_AMPLITUDE_M`,
  :data:`COM_FREQUENCY_HZ`) about the middle of the feet, the pelvis rocks in roll and pitch, and
  the posture task carries the upper body's Fourier excitation (the torso orientation task follows
  the waist); all of it ramps in over :data:`RAMP_S` and is scaled by the balance watch's amplitude
  factor (:class:`~mbctl.jobs.excite_g1_balance.BalanceWatch`: 0 once it has stopped the excitation);
* each step (:func:`step_starts`, :mod:`mbctl.jobs.excite_g1_steps`): the CoM goes over the other
  foot's sole (:data:`STANCE_INSET_M` short of its centre), the foot is released, lifted and put
  back where it stood, and the CoM goes back; a stopped excitation begins no step and cuts the one
  under way short (its foot is put down).

The CoM reference carries its velocity and acceleration (the sway's, the ramp's, the shift's and
the scale's), so the CoM task tracks it instead of lagging.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from mbctl.jobs.excite_g1_balance import BalanceWatch
from mbctl.jobs.excite_g1_legs import SwingLegs
from mbctl.jobs.excite_g1_steps import STEP_TIMES_S, Steps
from mbctl.planners.fourier import FourierTrajectory
from mbctl.robots.g1 import FEET, PELVIS, TORSO
from mbctl.robots.interface import RobotState
from mbctl.robots.model_pair import Robot

#: CoM motion: amplitude [m] and frequency [Hz] along x, y (sway) and z (squat depth).
COM_AMPLITUDE_M = (0.02, 0.035, 0.04)
COM_FREQUENCY_HZ = (0.23, 0.31, 0.4)
#: Pelvis roll and pitch: amplitude [rad] and frequencies [Hz].
PELVIS_AMPLITUDE_RAD = 0.05
PELVIS_FREQUENCY_HZ = (0.17, 0.27)
#: Ramp-in [s] of every motion from standing still.
RAMP_S = 1.5
#: Over one foot the CoM goes this far [m] short of the sole's centre, toward the other foot: the
#: stance ankle's roll then stays off its limit (0.26 rad; at the centre it needs 0.24) and the
#: sole's 2.5 cm half-width still leaves the CoP 1.5 cm.
STANCE_INSET_M = 0.01
#: Fraction by which the upper body's and the pelvis's motion shrink while the CoM is over one foot.
STEP_CALM = 0.8
#: The steps run only in excitations at least this long [s] (the ramp-in and two steps fit).
MIN_DURATION_FOR_STEPS_S = 16.0



@dataclass
class Schedule:
    """Task references over time: CoM, pelvis and torso orientation, posture, contacts.

    Attributes:
        wb: The standing whole-body controller (:class:`~mbctl.control.wbc.Standing`).
        robot: The plant's robot (joint names and indices).
        model: The controller's model (the schedule's own kinematics).
        upper: The upper body's Fourier excitation.
        q0: The start configuration (nq,).
        steps: (foot, start [s]) of each step.
        watch: The balance watch whose amplitude factor scales the motion.
        com_ref: The CoM reference (3,) [m] of the last cycle.
    """

    wb: Any           # what g1_whole_body returns (its controller and com/pelvis/torso/posture tasks)
    robot: Robot      # the plant's robot (joint names and indices)
    model: pin.Model  # the controller's model (the schedule's own kinematics)
    upper: FourierTrajectory
    q0: np.ndarray
    steps: list[tuple[str, float]]
    watch: BalanceWatch

    def __post_init__(self) -> None:
        model = self.model
        self.data = model.createData()
        self.iq_upper = np.array([self.robot.joint(j).idx_q for j in self.upper.names])
        self.torso_fid, self.pelvis_fid = model.getFrameId(TORSO), model.getFrameId(PELVIS)
        self.c0 = np.array(pin.centerOfMass(model, self.data, self.q0))
        self.com_ref = self.c0.copy()
        ctrl = self.wb.controller
        self.sole_F = {f: ctrl.contacts[f].contact.points_F.mean(axis=0) for f in FEET}  # sole centres
        self.mid0 = self._feet_middle()
        self.legs = SwingLegs(model, FEET)  # each foot's swing task and leg IK, and its record
        self.stepper = Steps(ctrl, model, self.steps, self.legs)

    def _sole_centre(self, foot: str) -> np.ndarray:
        """The centre (3,) [m] in W of ``foot``'s sole where the controller holds (or last held) it."""
        return self.wb.controller.contacts[foot].X_WF0.act(self.sole_F[foot])

    def _feet_middle(self) -> np.ndarray:
        return 0.5 * (self._sole_centre(FEET[0]) + self._sole_centre(FEET[1]))

    def _orientation_torso(self, R_pelvis: np.ndarray, q: np.ndarray) -> np.ndarray:
        """The torso's world orientation with the pelvis at R_pelvis and the waist at q's."""
        model = self.model
        pin.framesForwardKinematics(model, self.data, q)
        X_PT = self.data.oMf[self.pelvis_fid].actInv(self.data.oMf[self.torso_fid])
        return R_pelvis @ X_PT.rotation

    def update(self, t: float, state: RobotState) -> None:
        """Set every task's reference for time ``t`` [s] at the measured ``state``."""
        step = self.stepper.phase(t, state, self.watch.stopped_at_s)
        ramp, dramp, ddramp = _smooth(t, RAMP_S)
        scale, dscale, ddscale = self.watch.scale_at(t)
        amp = ramp * scale  # the motion's amplitude: ramped in, scaled by the balance watch
        damp, ddamp = dramp * scale + ramp * dscale, ddramp * scale + 2.0 * dramp * dscale + ramp * ddscale
        # over one foot the upper body and the pelvis calm down: a small sole bears little moment
        calm = amp * (1.0 - STEP_CALM * (step[1][0] if step is not None else 0.0))
        q_ref = self.q0.copy()
        q_up, _, _ = self.upper.sample([t])
        start = self.upper.q_start  # the opened arms the oscillation starts from, at rest
        q_ref[self.iq_upper] = (self.q0[self.iq_upper] + ramp * (start - self.q0[self.iq_upper])
                                + calm * (q_up[0] - start))
        w = 2 * np.pi * np.asarray(COM_FREQUENCY_HZ)
        A = np.asarray(COM_AMPLITUDE_M)
        sway = np.array([A[0] * np.sin(w[0] * t), A[1] * np.sin(w[1] * t), -A[2] * (1 - np.cos(w[2] * t))])
        dsway = np.array([A[0] * w[0] * np.cos(w[0] * t), A[1] * w[1] * np.cos(w[1] * t),
                          -A[2] * w[2] * np.sin(w[2] * t)])
        ddsway = np.array([-A[0] * w[0] ** 2 * np.sin(w[0] * t), -A[1] * w[1] ** 2 * np.sin(w[1] * t),
                           -A[2] * w[2] ** 2 * np.cos(w[2] * t)])
        centre = self.c0.copy()  # the sway's centre moves with the feet (a foot put down a little off)
        centre[:2] += (self._feet_middle() - self.mid0)[:2]
        com = centre + amp * sway
        dcom = amp * dsway + damp * sway
        ddcom = amp * ddsway + 2.0 * damp * dsway + ddamp * sway
        if step is not None:  # a step: the CoM over the stance foot's sole, sway and squat paused
            foot, (s_shift, ds, dds) = step
            stance = self._sole_centre(FEET[1] if foot == FEET[0] else FEET[0])
            inward = self._sole_centre(foot)[:2] - stance[:2]  # toward the free foot
            stance[:2] += STANCE_INSET_M * inward / np.linalg.norm(inward)
            gap = np.array([stance[0], stance[1], self.c0[2]]) - com
            com, dcom, ddcom = (com + s_shift * gap, (1 - s_shift) * dcom + ds * gap,
                                (1 - s_shift) * ddcom - 2.0 * ds * dcom + dds * gap)
        for foot, target in self.stepper.free.items():
            idx_q, q_leg = self.legs.track(t, foot, *target, state.q)
            q_ref[idx_q] = q_leg
        self.com_ref = com
        self.wb.com.set_target(com, dcom, ddcom)
        wp = 2 * np.pi * np.asarray(PELVIS_FREQUENCY_HZ)
        roll, pitch = calm * PELVIS_AMPLITUDE_RAD * np.sin(wp * t)
        R_pelvis = pin.rpy.rpyToMatrix(roll, pitch, 0.0)
        self.wb.base.set_target(pin.SE3(R_pelvis, np.zeros(3)))
        q_fk = q_ref.copy()
        q_fk[:7] = [0, 0, 0, 0, 0, 0, 1]
        self.wb.torso.set_target(pin.SE3(self._orientation_torso(R_pelvis, q_fk), np.zeros(3)))
        self.wb.posture.set_target(q_ref)


def _smooth(t: float, duration: float) -> tuple[float, float, float]:
    """The smooth step ``3 x^2 - 2 x^3`` of ``x = t / duration`` (0, 1 outside), its rates [1/s, 1/s^2]."""
    x = t / duration
    if x <= 0.0 or x >= 1.0:
        return float(x >= 1.0), 0.0, 0.0
    return x * x * (3 - 2 * x), 6 * x * (1 - x) / duration, (6 - 12 * x) / duration**2


def step_starts(duration_s: float) -> list[tuple[str, float]]:
    """The steps of an excitation ``duration_s`` long: (foot, start [s]), one after the other.

    They begin after the ramp-in; none when the two do not fit (shorter than
    :data:`MIN_DURATION_FOR_STEPS_S`).
    """
    if duration_s < MIN_DURATION_FOR_STEPS_S:
        return []
    total = sum(STEP_TIMES_S)
    first = max(RAMP_S, 0.45 * duration_s - total)
    second = max(first + total, 0.8 * duration_s - total)
    return [(FEET[0], first), (FEET[1], second)] if second + total <= duration_s else []


