"""Joint-space PD control with torque output.

For each controlled joint i::

    tau_i = kp_i (q_ref_i - q_i) + kd_i (v_ref_i - v_i)        [N m]

clipped to the actuator's torque limits (clips are counted). Without gravity compensation a
joint under load settles with the steady-state error ``g_i(q) / kp_i``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from mbctl.control.controller import JointMap, JointReference, TorqueSaturation
from mbctl.control.gains import PDGains
from mbctl.robots.commands import Command, CommandKind
from mbctl.robots.interface import RobotState
from mbctl.robots.model_pair import Robot


class JointPD:
    """PD on joint positions and velocities; outputs torques for the controlled joints.

    Args:
        robot: The robot (its actuators name the controlled joints).
        gains: kp [N m/rad], kd [N m s/rad]; one pair (repeated) or one per joint.
        joints: Controlled joints (default: every actuated joint, actuator order).
        saturate: Clip torques to the actuator limits (and count the clips).

    Raises:
        GainsError: Gains that do not match the number of joints.
        ControllerSetupError: Joints that cannot be controlled (see ``JointMap.from_robot``).
        UnknownNameError: An unknown joint name.
    """

    name = "pd"
    reference_type = JointReference

    def __init__(
        self,
        robot: Robot,
        gains: PDGains,
        joints: Sequence[str] | None = None,
        *,
        saturate: bool = True,
    ):
        self.robot = robot
        self.joint_map = JointMap.from_robot(robot, joints)
        self.gains = gains.broadcast(self.joint_map.size)
        self.saturation = TorqueSaturation(self.joint_map, saturate)
        self._idx_q = self.joint_map.q_selector
        self._idx_v = self.joint_map.v_selector
        self._names = self.joint_map.command_names
        self._kp = np.asarray(self.gains.kp)
        self._kd = np.asarray(self.gains.kd)
        self._tau = np.zeros(self.joint_map.size)
        self._ev = np.zeros(self.joint_map.size)

    @property
    def joints(self) -> tuple[str, ...]:
        """Controlled joint names, the order of references and torques."""
        return self.joint_map.joints

    def reset(self) -> None:
        """Zero the saturation counters."""
        self.saturation.reset()

    def feedback(self, state: RobotState, reference: JointReference) -> np.ndarray:
        """``kp e + kd de`` (n,) [N m] into an internal buffer (overwritten on the next call)."""
        tau, ev = self._tau, self._ev
        np.subtract(reference.q, state.q[self._idx_q], out=tau)
        tau *= self._kp
        np.subtract(reference.v, state.v[self._idx_v], out=ev)
        ev *= self._kd
        tau += ev
        return tau

    def compute(self, state: RobotState, reference: JointReference) -> Command:
        """Torque command (n,) [N m] for the controlled joints."""
        tau = self.feedback(state, reference)
        return Command(CommandKind.TORQUE, self.saturation.apply(tau), self._names)
