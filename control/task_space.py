"""Task-space computed torque for a point on a fully actuated arm (e.g. the 2-link end effector).

Notation: W world frame, S the controlled site (a Pinocchio frame). ``p_WS`` is the site position
restricted to the task axes (k of x, y, z), ``J(q)`` (k, nv) its Jacobian in W
(``LOCAL_WORLD_ALIGNED``) and ``dJ v`` the velocity-product acceleration (the classical
acceleration of S at zero joint acceleration). With ``e = p_ref - p_WS`` and
``de = v_ref - J v``::

    a_task = a_ref + kp e + kd de                          [m/s^2]
    a_des  = J^+ (a_task - dJ v)                           [rad/s^2]
    tau    = M(q) a_des + b(q, v)                          [N m]

(``J^+ = J^-1`` when J is square, as on the 2-link arm in its plane). With an exact model the
task error obeys ``e'' + kd e' + kp e = 0`` away from singularities (``det J -> 0`` makes a_des,
and the torques, blow up; saturation then clips them). Gains are per unit mass:
``kp = omega^2`` [1/s^2], ``kd = 2 zeta omega`` [1/s].
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from mbctl.control.controller import ControllerBase, JointMap, TaskReference
from mbctl.control.exceptions import ControllerSetupError, ReferenceMismatch, SingularJacobian
from mbctl.control.gains import PDGains
from mbctl.robots.commands import Command, CommandKind
from mbctl.robots.interface import RobotState
from mbctl.robots.model_pair import Robot

_AXES = {"x": 0, "y": 1, "z": 2}


class TaskSpaceComputedTorque(ControllerBase):
    """Computed torque on the position of one frame, over chosen world axes.

    Args:
        robot: A fixed-base robot whose every dof is an actuated joint.
        gains: Per-unit-mass gains kp [1/s^2], kd [1/s]; one pair or one per task axis.
        frame: Site or body name (a Pinocchio frame), default "end_effector".
        axes: World axes controlled, e.g. "xy" for the planar arm.
        pin_model: The analytic model (default ``robot.pin_model``).
        saturate: Clip torques to the actuator limits (and count the clips).

    Raises:
        ControllerSetupError: Unknown axes, actuators that do not take torques (position,
            velocity), a floating base or unactuated dofs, a model of another size.
        UnknownNameError: Unknown frame or joint.
        GainsError: Gains that do not match the number of axes.

    ``compute`` raises ReferenceMismatch for a reference of the wrong size and SingularJacobian
    where J cannot be inverted.
    """

    name = "task_space_ct"
    reference_type = TaskReference

    def __init__(
        self,
        robot: Robot,
        gains: PDGains,
        frame: str = "end_effector",
        axes: str = "xy",
        *,
        joints: Sequence[str] | None = None,
        pin_model: pin.Model | None = None,
        saturate: bool = True,
    ):
        if not axes or any(a not in _AXES for a in axes) or len(set(axes)) != len(axes):
            raise ControllerSetupError(f"axes must be distinct letters of 'xyz'; got {axes!r}")
        super().__init__(robot, JointMap.from_robot(robot, joints), saturate)
        self._require_every_dof("task-space computed torque")
        self._use_model(pin_model)
        self.frame_id = robot.frame_id(frame)
        self.frame = frame
        self.axes = axes
        self._rows = np.array([_AXES[a] for a in axes], dtype=int)
        self.gains = gains.broadcast(len(axes))
        self._idx_v = self.joint_map.v_selector
        self._zero_a = np.zeros(robot.nv)
        self._square = len(axes) == robot.nv

    def compute(self, state: RobotState, reference: TaskReference) -> Command:
        """Torque command (n,) [N m] moving the frame along ``reference`` (task axes, W)."""
        model, data, fid, rows = self.model, self.data, self.frame_id, self._rows
        if reference.p.shape != rows.shape:
            raise ReferenceMismatch(
                f"task reference p must have shape {rows.shape} (axes {self.axes!r}); "
                f"got {reference.p.shape}"
            )
        q, v = state.q, state.v
        pin.forwardKinematics(model, data, q, v, self._zero_a)
        pin.updateFramePlacement(model, data, fid)
        frame = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        dJv = pin.getFrameClassicalAcceleration(model, data, fid, frame).linear[rows]
        p = data.oMf[fid].translation[rows]
        J = pin.computeFrameJacobian(model, data, q, fid, frame).reshape(6, -1)[rows]  # (6,) if nv = 1
        a_task = reference.a + self.gains.kp * (reference.p - p) + self.gains.kd * (
            reference.v - J @ v
        )
        rhs = a_task - dJv
        try:
            a_des = np.linalg.solve(J, rhs) if self._square else np.linalg.pinv(J) @ rhs
        except np.linalg.LinAlgError as exc:
            raise SingularJacobian(
                f"task Jacobian of {self.frame!r} on axes {self.axes!r} is singular at "
                f"q={np.round(q, 6).tolist()} rad; keep the reference away from singular "
                "configurations (e.g. the stretched 2-link arm)", q.copy()
            ) from exc
        tau = pin.rnea(model, data, q, v, a_des)[self._idx_v]
        return Command(CommandKind.TORQUE, self.saturation.apply(tau), self._names)
