"""Joint-space computed torque (inverse dynamics) on a fully actuated robot.

With ``e = q_ref - q`` and ``de = v_ref - v``::

    a_des = a_ref + kp e + kd de                          [rad/s^2]
    tau   = M(q) a_des + b(q, v) + tau_f(v_ref)           [N m]

``M(q)`` includes the rotor armature and ``b(q, v) = C(q, v) v + g(q)``; both come from one
recursive Newton-Euler pass of the Pinocchio model (``pin.rnea(q, v, a_des)``). If the model is
exact the error obeys ``e'' + kd e' + kp e = 0``, so the gains are per unit inertia:
``kp = omega^2`` [1/s^2], ``kd = 2 zeta omega`` [1/s] (``gains_from_frequency(omega, zeta)``).

``tau_f`` is the model's joint friction feed-forward: Coulomb ``friction * sign(v_ref)`` (zero
where ``|v_ref|`` is below ``friction_deadband_rad_s``) plus viscous ``damping * v_ref``, from
the Pinocchio model's ``friction`` and ``damping`` (read from the MJCF's ``frictionloss`` and
``damping``). Zero on models without joint friction.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from mbctl.control.controller import JointFeedbackController, JointReference
from mbctl.control.gains import PDGains
from mbctl.robots.commands import Command, CommandKind
from mbctl.robots.interface import RobotState
from mbctl.robots.model_pair import Robot

#: Reference speed [rad/s] below which no Coulomb friction feed-forward is applied.
FRICTION_DEADBAND_RAD_S = 1e-3

_TORQUE = CommandKind.TORQUE  # an enum member read per cycle: a global costs a quarter of it


class ComputedTorque(JointFeedbackController):
    """Joint-space computed torque over every dof of a fixed-base, fully actuated robot.

    Args:
        robot: The robot; every dof must be a controlled (actuated, 1-dof) joint.
        gains: Per-unit-inertia gains kp [1/s^2], kd [1/s]; one pair or one per joint.
        joints: Controlled joints (default: every actuated joint, actuator order).
        pin_model: The analytic model (default ``robot.pin_model``; a perturbed copy for
            model-error studies). Same nq and nv as the robot.
        friction_feedforward: Add the model's Coulomb and viscous joint friction at v_ref.
        saturate: Clip torques to the actuator limits (and count the clips).

    Raises:
        GainsError: Gains that do not match the number of joints.
        ControllerSetupError: Actuators that do not take torques (position, velocity), a
            floating base or unactuated dofs, or a model of another size.
        UnknownNameError: An unknown joint name.
    """

    name = "computed_torque"

    def __init__(
        self,
        robot: Robot,
        gains: PDGains,
        joints: Sequence[str] | None = None,
        *,
        pin_model: pin.Model | None = None,
        friction_feedforward: bool = True,
        saturate: bool = True,
    ):
        super().__init__(robot, gains, joints, saturate=saturate)  # checks the actuators take torques
        self._require_every_dof("computed torque")
        self._use_model(pin_model)
        friction = np.asarray(self.model.friction)[self._idx_v]
        damping = np.asarray(self.model.damping)[self._idx_v]
        self._friction = friction if friction_feedforward and np.any(friction) else None
        self._damping = damping if friction_feedforward and np.any(damping) else None
        self._a_full = np.zeros(robot.nv)

    def desired_acceleration(self, state: RobotState, reference: JointReference) -> np.ndarray:
        """``a_des = a_ref + kp e + kd de`` (n,) [rad/s^2] (internal buffer)."""
        return self.feedback(state, reference, reference.a)

    def compute(self, state: RobotState, reference: JointReference) -> Command:
        """Torque command (n,) [N m] for the controlled joints."""
        a = self.feedback(state, reference, reference.a)  # desired_acceleration(), one call less
        if self._identity:
            # a view of the controller's own pin.Data.tau: clipped in place, copied by Command
            tau = pin.rnea(self.model, self.data, state.q, state.v, a)
        else:
            self._a_full[self._idx_v] = a
            tau = pin.rnea(self.model, self.data, state.q, state.v, self._a_full)[self._idx_v].copy()
        if self._friction is not None:
            v_ref = reference.v
            tau += self._friction * np.sign(v_ref) * (np.abs(v_ref) > FRICTION_DEADBAND_RAD_S)
        if self._damping is not None:
            tau += self._damping * reference.v
        return Command(_TORQUE, self.saturation.apply(tau), self._names)
