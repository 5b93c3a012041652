"""The position of a frame origin: ``e = p_WF - p_WT`` (3,) [m] in W.

Velocity level: ``J_e = R_WF J_F[:3]`` (the frame's Jacobian, linear rows, in world-aligned axes).
Acceleration level: ``J`` the same rows (LOCAL_WORLD_ALIGNED), drift the classical acceleration
of F's origin at zero vdot, ``a_des = a_ref - kp e + kd (v_ref - J v)``, all in W.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from mbctl.control.exceptions import TaskSetupError
from mbctl.control.tasks.base import AccelerationGains
from mbctl.control.tasks.frame import FrameTask, world_vector
from mbctl.control.tasks.residuals import TaskResidual
from mbctl.control.tasks.state import DynamicsState, TaskState


class FramePositionTask(FrameTask):
    """Position of a frame origin: ``e = p_WF - p_WT`` (3,) [m] in W, ``J_e = R_WF J_F[:3]``."""

    def __init__(
        self,
        frame: str,
        model: TaskState | pin.Model,
        cost: npt.ArrayLike = 1.0,
        gain: float = 1.0,
        lm_damping: float = 0.0,
        name: str | None = None,
        servo: AccelerationGains | None = None,
    ):
        """Create the task (set a target before solving).

        Args:
            frame: Pinocchio frame name.
            model: Pinocchio model or task state.
            cost: Weight(s) [cost]/[m] along world x, y, z, scalar or (3,).
            gain: Velocity level: fraction of the error corrected per step, in [0, 1].
            lm_damping: Velocity level: Levenberg-Marquardt scale [-].
            name: Report label (default: "<frame> position").
            servo: Acceleration level: PD gains.

        Raises:
            UnknownNameError: No frame called ``frame``.
            TaskSetupError: Invalid cost, gain or damping.
        """
        super().__init__(name or f"{frame} position", frame, model, 3, cost, gain, lm_damping, servo)

    def set_target(self, transform_target_to_world: pin.SE3 | npt.ArrayLike,
                   v: npt.ArrayLike = (0.0, 0.0, 0.0), a: npt.ArrayLike = (0.0, 0.0, 0.0)) -> None:
        """Set the target position ``p_WT`` (3,) [m] (an SE3's translation is used), velocity, acceleration.

        Raises:
            TaskSetupError: Not a finite (3,) position, velocity or acceleration.
        """
        if isinstance(transform_target_to_world, pin.SE3):
            p = transform_target_to_world.translation.copy()
        else:
            try:
                p = world_vector(transform_target_to_world, self.name, "target position [m]")
            except TaskSetupError:
                raise TaskSetupError(f"{self.name}: target must be a finite (3,) position [m]; "
                                     f"got {transform_target_to_world!r}") from None
        self._set_pose(pin.SE3(np.eye(3), p), v, a)

    def compute_error(self, state: TaskState) -> np.ndarray:
        """``p_WF - p_WT`` (3,) [m]."""
        return state.frame_pose(self.frame_id).translation - self.transform_target_to_world.translation

    def compute_jacobian(self, state: TaskState) -> np.ndarray:
        """``R_WF J_F[:3]`` (3, nv)."""
        return state.frame_jacobian(self.frame_id, pin.LOCAL_WORLD_ALIGNED)[:3]

    def jacobian_and_drift(self, state: DynamicsState) -> tuple[np.ndarray, np.ndarray]:
        """``(J_F[:3], (Jdot_F v)[:3])`` in world-aligned axes."""
        ref = pin.LOCAL_WORLD_ALIGNED
        return state.frame_jacobian(self.frame_id, ref)[:3], state.frame_drift(self.frame_id, ref)[:3]

    def desired_acceleration(self, state: DynamicsState, J: np.ndarray) -> np.ndarray:
        """``a_ref - kp e + kd (v_ref - J v)`` (3,) [m/s^2] in W."""
        return self.a_ref_W - self._kp * self.compute_error(state) + self._kd * (self.v_ref_W - J @ state.v)

    def residual(self, state: TaskState) -> TaskResidual:
        """Distance to the target [m]."""
        return TaskResidual(position_m=float(np.linalg.norm(self.compute_error(state))))
