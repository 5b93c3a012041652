"""The pose of a frame: ``e = log6(X_FT)`` (6,) [m, rad] in F (the mink ``FrameTask``).

Velocity level: ``J_e = -Jlog6(X_TF) J_F`` with ``J_F`` the body Jacobian of F (its twist in F,
[v; w]), the exact derivative of the error (mink's ``SE3.jlog`` drops the translation-rotation
coupling at rotation errors below 1e-5 rad, where it tests ``theta^2 < 1e-10``; Pinocchio's ``Jlog6``
is exact: tests/control/ik/test_g1_ik.py shows the first steps differing by percents there).

Acceleration level (TSID): ``J = J_F`` (LOCAL), drift ``Jdot_F v`` (the spatial acceleration of F
at zero vdot), ``a_des = a_ref + kp log6(X_FT) + kd (v_ref - J_F v)``, with the linear references
rotated from W into F and zero angular references.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from mbctl.control.tasks.base import AccelerationGains, dot_into
from mbctl.control.tasks.frame import FrameTask, pose_cost
from mbctl.control.tasks.residuals import TaskResidual
from mbctl.control.tasks.state import DynamicsState, TaskState


class FramePoseTask(FrameTask):
    """Pose of a frame: ``e = log6(X_FT)`` (6,) [m, rad] in F; cost is (position [3], orientation [3])."""

    def __init__(
        self,
        frame: str,
        model: TaskState | pin.Model,
        position_cost: npt.ArrayLike = 1.0,
        orientation_cost: npt.ArrayLike = 1.0,
        gain: float = 1.0,
        lm_damping: float = 0.0,
        name: str | None = None,
        servo: AccelerationGains | None = None,
    ):
        """Create the task (set a target before solving).

        Args:
            frame: Pinocchio frame name (body, site, operational frame).
            model: Pinocchio model or task state.
            position_cost: Weight(s) on the translation error [cost]/[m], scalar or (3,).
            orientation_cost: Weight(s) on the rotation error [cost]/[rad], scalar or (3,).
            gain: Velocity level: fraction of the error corrected per step, in [0, 1].
            lm_damping: Velocity level: Levenberg-Marquardt scale [-].
            name: Report label (default: "<frame> pose").
            servo: Acceleration level: PD gains.

        Raises:
            UnknownNameError: No frame called ``frame``.
            TaskSetupError: Invalid costs, gain or damping.
        """
        cost = pose_cost(frame, position_cost, orientation_cost)
        super().__init__(name or f"{frame} pose", frame, model, 6, cost, gain, lm_damping, servo)

    def compute_error(self, state: TaskState) -> np.ndarray:
        """``log6(X_FT)`` (6,) [m, rad]: the twist from F to the target, in F."""
        return -pin.log6(self._X_TF(state)).vector

    def compute_jacobian(self, state: TaskState) -> np.ndarray:
        """``-Jlog6(X_TF) J_F`` (6, nv)."""
        return self.error_and_jacobian(state)[1]

    def error_and_jacobian(self, state: TaskState) -> tuple[np.ndarray, np.ndarray]:
        """Both, from one ``X_TF``."""
        X_TF = self._X_TF(state)
        J = pin.Jlog6(X_TF) @ state.frame_jacobian(self.frame_id)
        return -pin.log6(X_TF).vector, np.negative(J, out=J)

    def write_qp_rows(self, state: TaskState, W_t: np.ndarray, r_t: np.ndarray) -> float:
        """Fast path of ``Task.write_qp_rows`` (the hot path of IK): the same values.

        ``W_t = -diag(cost) Jlog6(X_TF) J_F`` and ``r_t = gain diag(cost) log6(X_TF)``, written in
        place with no temporaries for the negations.
        """
        X_TF = self._X_TF(state)
        _, neg_col, _, gain_cost = self._weights()
        np.matmul(pin.Jlog6(X_TF), state.frame_jacobian(self.frame_id), out=W_t)
        W_t *= neg_col
        np.multiply(gain_cost, pin.log6(X_TF).vector, out=r_t)
        return self._lm_term(r_t)

    def write_velocity_rows(self, state: TaskState, J_out: np.ndarray, e_out: np.ndarray) -> None:
        """The active rows of ``(-J_e, -e) = (Jlog6(X_TF) J_F, log6(X_TF))`` (both negated).

        A position-only task (orientation cost 0) multiplies the top half of ``Jlog6`` only.
        """
        if self._X_WT is None:
            raise self._no_target()
        # X_WT^-1 X_WF by actInv: one binding call, ~2x faster than the SE3 product's overload dispatch
        X_TF = self._X_WT.actInv(state.frame_placements[self.frame_id])
        J_F = state.frame_jacobian(self.frame_id)
        # np.dot: ~0.5 us against matmul's ~1.5 us for these small products (the same BLAS call)
        if self._all_active:
            dot_into(pin.Jlog6(X_TF), J_F, J_out)
            e_out[:] = pin.log6(X_TF).vector
        else:  # e.g. position only: 3 rows of Jlog6 (a view), not 6
            rows = self._index
            dot_into(pin.Jlog6(X_TF)[rows], J_F, J_out)
            e_out[:] = pin.log6(X_TF).vector[rows]

    def jacobian_and_drift(self, state: DynamicsState) -> tuple[np.ndarray, np.ndarray]:
        """``(J_F, Jdot_F v)`` in F (LOCAL)."""
        return state.frame_jacobian(self.frame_id, pin.LOCAL), state.frame_drift(self.frame_id, pin.LOCAL)

    def desired_acceleration(self, state: DynamicsState, J: np.ndarray) -> np.ndarray:
        """``a_ref + kp log6(X_FT) + kd (v_ref - J_F v)`` (6,) in F."""
        R_FW = state.frame_pose(self.frame_id).rotation.T
        v_ref = np.concatenate([R_FW @ self.v_ref_W, np.zeros(3)])
        a_ref = np.concatenate([R_FW @ self.a_ref_W, np.zeros(3)])
        return a_ref + self._kp * self.compute_error(state) + self._kd * (v_ref - J @ state.v)

    def residual(self, state: TaskState) -> TaskResidual:
        """Distance [m] and rotation angle [rad] to the target; a part with zero cost is left out."""
        X_TF = self._X_TF(state)
        position = float(np.linalg.norm(X_TF.translation)) if np.any(self.cost[:3] > 0.0) else None
        angle = float(np.linalg.norm(pin.log3(X_TF.rotation))) if np.any(self.cost[3:] > 0.0) else None
        return TaskResidual(position_m=position, orientation_rad=angle)
