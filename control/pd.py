"""Joint-space PD control with torque output.

For each controlled joint i::

    tau_i = kp_i (q_ref_i - q_i) + kd_i (v_ref_i - v_i)        [N m]

clipped to the actuator's torque limits (clips are counted). Without gravity compensation a
joint under load settles with the steady-state error ``g_i(q) / kp_i``.
"""

from __future__ import annotations

from mbctl.control.controller import JointFeedbackController, JointReference
from mbctl.robots.commands import Command, CommandKind
from mbctl.robots.interface import RobotState


class JointPD(JointFeedbackController):
    """PD on joint positions and velocities; outputs torques for the controlled joints.

    Args:
        robot: The robot (its actuators name the controlled joints).
        gains: kp [N m/rad], kd [N m s/rad]; one pair (repeated) or one per joint.
        joints: Controlled joints (default: every actuated joint, actuator order).
        saturate: Clip torques to the actuator limits (and count the clips).

    Raises:
        GainsError: Gains that do not match the number of joints.
        ControllerSetupError: Joints that cannot be controlled (see ``JointMap.from_robot``), or
            actuators that do not take torques (position, velocity).
        UnknownNameError: An unknown joint name.
    """

    name = "pd"

    def compute(self, state: RobotState, reference: JointReference) -> Command:
        """Torque command (n,) [N m] for the controlled joints."""
        tau = self.feedback(state, reference)
        return Command(CommandKind.TORQUE, self.saturation.apply(tau), self._names)
