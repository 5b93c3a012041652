"""Joint-space PD plus gravity compensation from the Pinocchio model.

For each controlled joint i::

    tau_i = kp_i (q_ref_i - q_i) + kd_i (v_ref_i - v_i) + g_i(q)        [N m]

with ``g(q) = d V / d q`` the generalized gravity of the analytic model
(``pin.computeGeneralizedGravity``), taken at the controlled joints' v-indices. On a fixed base
this removes the PD's steady-state sag. On a floating base g(q) is the gravity of the tree
*hanging* from the base; contact forces, not the controller, carry the base, so the PD absorbs
the difference.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from mbctl.control.controller import JointReference
from mbctl.control.gains import PDGains
from mbctl.control.pd import JointPD
from mbctl.robots.commands import Command, CommandKind
from mbctl.robots.interface import RobotState
from mbctl.robots.model_pair import Robot


class PDGravity(JointPD):
    """PD with gravity compensation ``g(q)`` from a Pinocchio model; torque output.

    Args:
        robot: The robot (its actuators name the controlled joints).
        gains: kp [N m/rad], kd [N m s/rad]; one pair (repeated) or one per joint.
        joints: Controlled joints (default: every actuated joint, actuator order).
        pin_model: The analytic model to compensate with (default ``robot.pin_model``; pass a
            perturbed copy to study model error). Same nq and nv as the robot.
        saturate: Clip torques to the actuator limits (and count the clips).

    Raises:
        GainsError: Gains that do not match the number of joints.
        ControllerSetupError: Uncontrollable joints, actuators that do not take torques
            (position, velocity), or a model of another size.
        UnknownNameError: An unknown joint name.
    """

    name = "pd_gravity"

    def __init__(
        self,
        robot: Robot,
        gains: PDGains,
        joints: Sequence[str] | None = None,
        *,
        pin_model: pin.Model | None = None,
        saturate: bool = True,
    ):
        super().__init__(robot, gains, joints, saturate=saturate)
        self._use_model(pin_model)

    def gravity(self, q: np.ndarray) -> np.ndarray:
        """Generalized gravity g(q) (nv,) [N m] of the analytic model, Pinocchio convention."""
        return pin.computeGeneralizedGravity(self.model, self.data, q)

    def compute(self, state: RobotState, reference: JointReference) -> Command:
        """Torque command (n,) [N m] for the controlled joints."""
        tau = self.feedback(state, reference)
        tau += self.gravity(state.q)[self._idx_v]
        return Command(CommandKind.TORQUE, self.saturation.apply(tau), self._names)
