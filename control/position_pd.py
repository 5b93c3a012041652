"""Joint PD executed by the robot's position actuators: the controller outputs position targets.

A MuJoCo position actuator (e.g. the Menagerie G1's) applies ``f = kp (u - q) - kv v`` for a
target ``u`` [rad], with its own ``kp`` [N m/rad] and ``kv`` [N m s/rad]. Choosing::

    u = q_ref + (kv v_ref + tau_ff) / kp

turns it into ``f = kp (q_ref - q) + kv (v_ref - v) + tau_ff``: the actuator's PD tracks the
reference velocity too, and ``tau_ff`` [N m] is a feed-forward, here the gravity ``g(q)`` of the
Pinocchio model (optional). The gains are the actuators' own (the plant's stiffness and damping
are integrated implicitly by MuJoCo, so stiff gains stay stable), or those a plant applies to
position targets (:meth:`PositionTargetPD.use_gains` with the plant's ``position_gains()``: a robot
over DDS may lower them to keep its motor law stable). Targets outside the actuator's ctrlrange are
clipped and counted.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace

import numpy as np
import pinocchio as pin

from mbctl.control.controller import ControllerBase, JointMap, JointReference
from mbctl.control.exceptions import ControllerSetupError
from mbctl.robots.commands import Command, CommandKind
from mbctl.robots.interface import RobotState
from mbctl.robots.model_pair import Robot


class PositionTargetPD(ControllerBase):
    """PD through position actuators, with optional gravity feed-forward; position-target output.

    Args:
        robot: The robot; every controlled joint must be driven by a position actuator.
        joints: Controlled joints (default: every actuated joint, actuator order).
        gravity_feedforward: Add ``g(q)`` of the Pinocchio model through the target offset.
        pin_model: The analytic model (default ``robot.pin_model``). Same nq and nv as the robot.

    Raises:
        ControllerSetupError: A joint driven by a non-position actuator, an actuator with
            ``kp <= 0``, or a model of another size.
        UnknownNameError: An unknown joint name.
    """

    name = "position_pd"
    command_kind = CommandKind.POSITION

    def __init__(
        self,
        robot: Robot,
        joints: Sequence[str] | None = None,
        *,
        gravity_feedforward: bool = True,
        pin_model: pin.Model | None = None,
    ):
        jmap = JointMap.from_robot(robot, joints)
        infos = [robot.actuator(a) for a in jmap.actuators]
        wrong = [f"{a.name} ({a.kind})" for a in infos if a.kind != "position" or a.kp <= 0]
        if wrong:
            raise ControllerSetupError(
                f"PositionTargetPD needs position actuators with kp > 0; got {', '.join(wrong[:6])}. "
                "Use JointPD or PDGravity (torque output) on motor actuators instead."
            )
        self.kp = np.array([a.kp for a in infos])
        self.kv = np.array([a.kv for a in infos])
        low = np.array([a.ctrl_range[0] for a in infos])
        high = np.array([a.ctrl_range[1] for a in infos])
        # the "torque" limits of this joint map are the actuators' ctrlrange: targets are clipped
        super().__init__(robot, replace(jmap, tau_low=low, tau_high=high))
        self._use_model(pin_model)
        self.gravity_feedforward = gravity_feedforward
        self._idx_v = jmap.v_selector
        self._kv_over_kp = self.kv / self.kp

    def use_gains(self, gains: Mapping[str, tuple[float, float]]) -> None:
        """Compute the targets for these (kp [N m/rad], kd [N m s/rad]) by joint (a plant's own).

        Raises:
            ControllerSetupError: A controlled joint missing from ``gains``, or its kp <= 0.
        """
        missing = [j for j in self.joints if j not in gains]
        weak = [f"{j} (kp {gains[j][0]:g})" for j in self.joints if j in gains and not gains[j][0] > 0]
        problems = [f"{what} {', '.join(joints)}" for what, joints in (("no gains for", missing),
                                                                       ("kp <= 0 on", weak)) if joints]
        if problems:
            raise ControllerSetupError("PositionTargetPD needs kp > 0 on every controlled joint; "
                                       + "; ".join(problems))
        self.kp = np.array([gains[j][0] for j in self.joints], dtype=float)
        self.kv = np.array([gains[j][1] for j in self.joints], dtype=float)
        self._kv_over_kp = self.kv / self.kp

    def compute(self, state: RobotState, reference: JointReference) -> Command:
        """Position-target command (n,) [rad] for the controlled joints' actuators."""
        u = reference.q + self._kv_over_kp * reference.v
        if self.gravity_feedforward:
            g = pin.computeGeneralizedGravity(self.model, self.data, state.q)
            u += g[self._idx_v] / self.kp
        return Command(CommandKind.POSITION, self.saturation.apply(u), self._names)
