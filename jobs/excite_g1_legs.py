"""The swing legs of the G1's excitation: each free foot's task in the whole-body QP, its leg IK, the record.

A free foot follows its target pose X_WT (where it left the floor, raised) by two means:

* a pose task on the foot in the whole-body QP (:data:`SWING_COST`, :data:`SWING_GAINS`, as the
  one-foot scenario's swing foot), added when the foot's contact is released and removed when it
  is put down. Without it the free leg had only the posture task (weight 0.05 against the CoM's
  10): the QP swung the light leg to move the CoM and the foot landed centimetres off and tilted
  (the payload excitation fell at t = 25.6 s, the 16 s one had an infeasible QP at t = 7.9 s);
* the leg's joints that reach X_WT from the measured state (the base where it is), for the
  posture task, so it does not pull against the foot task: a pose task on the foot
  (:class:`~mbctl.control.tasks.FramePoseTask`) solved by :class:`~mbctl.control.ik.ChainIK` (damped
  least squares within the joint limits, to :data:`LEG_IK_TOLERANCE`). Every solve is counted; one
  that does not converge (a target out of the leg's reach, or the step cap) is kept with its time
  and residual for the report, and its damped closest pose is what the posture task gets.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from mbctl.control.ik import ChainIK, IKResult, chain_joints
from mbctl.control.ik.loop import largest_of
from mbctl.control.tasks import AccelerationGains, FramePoseTask, Tolerance
from mbctl.control.wbc import WholeBodyController

#: The swing leg's inverse kinematics each control cycle (damped least squares on the leg, from the
#: measured state): its convergence tolerance (position [m], orientation [rad]), step cap, the
#: Levenberg-Marquardt damping [cost] and the foot task's error-scaled damping [-].
LEG_IK_TOLERANCE = Tolerance(position_m=1e-5, orientation_rad=1e-4)
LEG_IK_MAX_ITERATIONS = 20
LEG_IK_DAMPING = 1e-6
LEG_IK_LM_DAMPING = 1.0
#: The free foot's pose task in the whole-body QP: its weight (position [cost]/[m], orientation
#: [cost]/[rad]) and PD gains (natural frequency [rad/s], damping ratio), as the one-foot scenario's.
SWING_COST = (10.0, 10.0)
SWING_GAINS = AccelerationGains(20.0, 1.0)


class SwingLegs:
    """Each foot's leg IK, and what the solves did over a run.

    Attributes:
        solves: Leg IK solves (one per control cycle of a free foot).
        failures: (time [s], foot, position residual [m], orientation residual [rad]) of each solve
            that did not converge.
        max_position_m: Largest foot position residual [m] left by any solve.
        max_orientation_rad: Largest foot orientation residual [rad] left by any solve.
        max_iterations: Most steps a solve took.
    """

    def __init__(self, model: pin.Model, feet: Sequence[str]):
        """A pose task on each foot for the QP, and the chain IK of the joints between it and the base.

        Args:
            model: The controller's Pinocchio model (floating base).
            feet: The foot frames.

        Raises:
            IKSetupError: A foot that is not a frame of a limb.
        """
        self.swing = {f: FramePoseTask(f, model, *SWING_COST, name=f"{f} swing", servo=SWING_GAINS)
                      for f in feet}
        self._task = {f: FramePoseTask(f, model, lm_damping=LEG_IK_LM_DAMPING) for f in feet}
        self._ik = {f: ChainIK(model, [self._task[f]], chain_joints(model, f), LEG_IK_DAMPING) for f in feet}
        self.solves = 0
        self.failures: list[tuple[float, str, float, float]] = []
        self.max_position_m = 0.0
        self.max_orientation_rad = 0.0
        self.max_iterations = 0

    def lift(self, controller: WholeBodyController, foot: str, X_WT: pin.SE3) -> None:
        """Put ``foot``'s swing task into ``controller``'s QP, its target ``X_WT`` at rest (foot free)."""
        self.swing[foot].set_target(X_WT)
        controller.add_task(self.swing[foot])

    def land(self, controller: WholeBodyController, foot: str) -> None:
        """Take ``foot``'s swing task out of the QP and put the foot down where it is (force ramp up)."""
        controller.remove_task(self.swing[foot])
        controller.touch_down(foot)

    def track(self, t: float, foot: str, X_WT: pin.SE3, v_W: npt.ArrayLike, a_W: npt.ArrayLike,
              q: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """The swing task's target (pose, linear velocity [m/s], acceleration [m/s^2] in W), and its leg IK.

        Returns:
            What :meth:`solve` returns for ``X_WT`` from ``q``.
        """
        self.swing[foot].set_target(X_WT, v_W, a_W)
        return self.solve(t, foot, X_WT, q)

    def solve(self, t: float, foot: str, X_WT: pin.SE3, q: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """The leg joints that put ``foot`` at ``X_WT`` from the state ``q`` (nq,) at time ``t`` [s].

        Returns:
            The leg's configuration indices and their values [rad] (the closest pose found when the
            solve did not converge; it is then recorded in :attr:`failures`).
        """
        ik = self._ik[foot]
        self._task[foot].set_target(X_WT)
        result = ik.solve(q, LEG_IK_TOLERANCE, LEG_IK_MAX_ITERATIONS)
        self._count(t, foot, result)
        return ik.idx_q, result.q[ik.idx_q]

    def _count(self, t: float, foot: str, result: IKResult) -> None:
        residual = largest_of(list(result.residuals.values()))
        position, angle = residual.position_m or 0.0, residual.orientation_rad or 0.0
        self.solves += 1
        self.max_position_m = max(self.max_position_m, position)
        self.max_orientation_rad = max(self.max_orientation_rad, angle)
        self.max_iterations = max(self.max_iterations, result.iterations)
        if not result.converged:
            self.failures.append((t, foot, position, angle))

    def section(self) -> dict[str, Any]:
        """JSON-ready: the counts, the largest residuals and the first failures."""
        return {"solves": self.solves, "not_converged": len(self.failures),
                "max_position_residual_m": self.max_position_m,
                "max_orientation_residual_rad": self.max_orientation_rad,
                "max_iterations": self.max_iterations,
                "tolerance": {"position_m": LEG_IK_TOLERANCE.position_m,
                              "orientation_rad": LEG_IK_TOLERANCE.orientation_rad},
                "first_failures": [{"t_s": t, "foot": f, "position_m": p, "orientation_rad": a}
                                   for t, f, p, a in self.failures[:10]]}

    def line(self) -> str:
        """The summary line: every solve converged, or how many did not and the first one."""
        text = (f"swing-leg IK: {self.solves} solves (tol {LEG_IK_TOLERANCE.position_m * 1e3:g} mm, "
                f"{LEG_IK_TOLERANCE.orientation_rad:g} rad), at most {self.max_iterations} iterations, ")
        if not self.failures:
            return text + "all converged"
        t, foot, position, angle = self.failures[0]
        return text + (f"{len(self.failures)} did NOT converge (first {foot} at t={t:.2f} s: "
                       f"{position * 1e3:.2f} mm, {angle:.3g} rad: out of the leg's reach, or the step cap)")
