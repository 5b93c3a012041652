"""The orientation of a frame: ``e = log3(R_FT)`` (3,) [rad] about F's axes.

Velocity level: ``J_e = -Jlog3(R_TF) J_F[3:]``. Acceleration level: ``J = J_F[3:]`` (LOCAL),
drift the angular part of F's spatial acceleration at zero vdot, ``a_des = kp e - kd J v``
(the target is at rest).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from mbctl.control.tasks.base import AccelerationGains, dot_into
from mbctl.control.tasks.frame import FrameTask
from mbctl.control.tasks.residuals import TaskResidual
from mbctl.control.tasks.state import DynamicsState, TaskState


class FrameOrientationTask(FrameTask):
    """Orientation of a frame: ``e = log3(R_FT)`` (3,) [rad], ``J_e = -Jlog3(R_TF) J_F[3:]``."""

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
            cost: Weight(s) [cost]/[rad] about the frame's axes, scalar or (3,).
            gain: Velocity level: fraction of the error corrected per step, in [0, 1].
            lm_damping: Velocity level: Levenberg-Marquardt scale [-].
            name: Report label (default: "<frame> orientation").
            servo: Acceleration level: PD gains.

        Raises:
            UnknownNameError: No frame called ``frame``.
            TaskSetupError: Invalid cost, gain or damping.
        """
        super().__init__(name or f"{frame} orientation", frame, model, 3, cost, gain, lm_damping, servo)

    def compute_error(self, state: TaskState) -> np.ndarray:
        """``log3(R_FT) = -log3(R_TF)`` (3,) [rad]."""
        return -pin.log3(self._X_TF(state).rotation)

    def compute_jacobian(self, state: TaskState) -> np.ndarray:
        """``-Jlog3(R_TF) J_F[3:]`` (3, nv)."""
        return self.error_and_jacobian(state)[1]

    def error_and_jacobian(self, state: TaskState) -> tuple[np.ndarray, np.ndarray]:
        """Both, from one ``R_TF``."""
        R_TF = self._X_TF(state).rotation
        J = pin.Jlog3(R_TF) @ state.frame_jacobian(self.frame_id)[3:]
        return -pin.log3(R_TF), np.negative(J, out=J)

    def write_velocity_rows(self, state: TaskState, J_out: np.ndarray, e_out: np.ndarray) -> None:
        """The active rows of ``(-J_e, -e) = (Jlog3(R_TF) J_F[3:], log3(R_TF))`` (both negated)."""
        if self._X_WT is None:
            raise self._no_target()
        # X_WT^-1 X_WF by one binding call (see FramePoseTask)
        R_TF = self._X_WT.actInv(state.frame_placements[self.frame_id]).rotation
        J_w = state.frame_jacobian(self.frame_id)[3:]
        if self._all_active:
            dot_into(pin.Jlog3(R_TF), J_w, J_out)
            e_out[:] = pin.log3(R_TF)
        else:
            rows = self._index
            dot_into(pin.Jlog3(R_TF)[rows], J_w, J_out)
            e_out[:] = pin.log3(R_TF)[rows]

    def jacobian_and_drift(self, state: DynamicsState) -> tuple[np.ndarray, np.ndarray]:
        """``(J_F[3:], (Jdot_F v)[3:])`` in F."""
        fid = self.frame_id
        return state.frame_jacobian(fid, pin.LOCAL)[3:], state.frame_drift(fid, pin.LOCAL)[3:]

    def desired_acceleration(self, state: DynamicsState, J: np.ndarray) -> np.ndarray:
        """``kp log3(R_FT) - kd J v`` (3,) [rad/s^2] in F."""
        return self._kp * self.compute_error(state) - self._kd * (J @ state.v)

    stacked_acceleration = True

    def constant_acceleration_jacobian(self, state: DynamicsState) -> np.ndarray | None:
        """``J_F[3:]`` (3, nv) for a frame fixed to a free-flyer root (the same at every state), else None."""
        if state.on_free_root(self.frame_id):
            return state.frame_jacobian(self.frame_id, pin.LOCAL)[3:].copy()
        return None

    def write_acceleration_terms(self, state: DynamicsState, J_t: np.ndarray, r_t: np.ndarray) -> None:
        """``J_F[3:]`` and ``kp log3(R_FT) - (Jdot_F v)[3:]`` (see ``Task.write_acceleration_terms``).

        On a free-flyer root the Jacobian is constant (written once by the stack) and the drift zero
        (:meth:`~mbctl.control.tasks.state.DynamicsState.on_free_root`): only the error is written.
        """
        if self._X_TW is None:
            raise self._no_target()
        fid = self.frame_id
        R_TF = np.dot(self._R_TW, state.frame_placements[fid].rotation)
        np.multiply(pin.log3(R_TF), -self._kp, out=r_t)  # kp log3(R_FT)
        if not state.on_free_root(fid):
            J_t[:] = state.frame_jacobian(fid, pin.LOCAL)[3:]
            r_t -= state.frame_angular_drift(fid)

    def residual(self, state: TaskState) -> TaskResidual:
        """Rotation angle to the target [rad]."""
        return TaskResidual(orientation_rad=float(np.linalg.norm(self.compute_error(state))))
