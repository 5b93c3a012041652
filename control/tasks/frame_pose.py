"""The pose of a frame: ``e = log6(X_FT)`` (6,) [m, rad] in F (the mink ``FrameTask``).

Velocity level: ``J_e = -Jlog6(X_TF) J_F`` with ``J_F`` the body Jacobian of F (its twist in F,
[v; w]), the exact derivative of the error (mink's ``SE3.jlog`` drops the translation-rotation
coupling at rotation errors below 1e-5 rad, where it tests ``theta^2 < 1e-10``; Pinocchio's ``Jlog6``
is exact: tests/control/ik/test_g1_ik.py shows the first steps differing by percents there).

Acceleration level (TSID): ``J = J_F`` (LOCAL), drift ``Jdot_F v`` (the spatial acceleration of F
at zero vdot), ``a_des = a_ref + kp log6(X_FT) + kd (v_ref - J_F v)``, with the references (linear
from :meth:`~mbctl.control.tasks.frame.FrameTask.set_target`, angular from
:meth:`FramePoseTask.set_angular_reference`, zero unless set) rotated from W into F. The task's
terms are stacked (:meth:`FramePoseTask.write_acceleration_terms`) unless a subclass has its own
law (``desired_acceleration``).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from mbctl.control.tasks.base import AccelerationGains, dot_into
from mbctl.control.tasks.frame import FrameTask, pose_cost, world_vector
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
        # the references in W, linear then angular: velocities [m/s; rad/s], accelerations [m/s^2;
        # rad/s^2] (v_ref_W and a_ref_W are their first rows: set_target writes into them)
        self._vel_W, self._acc_W = np.zeros((2, 3)), np.zeros((2, 3))
        self.v_ref_W, self.a_ref_W = self._vel_W[0], self._acc_W[0]
        self._ff_W = np.zeros((2, 3))  # a_ref + kd v_ref, per row (written per cycle)

    def __init_subclass__(cls, **kwargs: object) -> None:
        super().__init_subclass__(**kwargs)
        # a subclass with a law of its own writes its rows whole (its desired_acceleration), unless it says
        if cls.desired_acceleration is not FramePoseTask.desired_acceleration and "stacked_acceleration" \
                not in cls.__dict__:
            cls.stacked_acceleration = False

    @property
    def w_ref_W(self) -> np.ndarray:
        """Target angular velocity (3,) [rad/s] in W (acceleration level; a view)."""
        return self._vel_W[1]

    @property
    def alpha_ref_W(self) -> np.ndarray:
        """Target angular acceleration (3,) [rad/s^2] in W (acceleration level; a view)."""
        return self._acc_W[1]

    def _set_pose(self, X_WT: pin.SE3, v: npt.ArrayLike, a: npt.ArrayLike) -> None:
        super()._set_pose(X_WT, v, a)
        self._vel_W[1] = self._acc_W[1] = 0.0  # a new target: at rest in rotation until said otherwise

    def set_angular_reference(self, w: npt.ArrayLike = (0.0, 0.0, 0.0),
                              alpha: npt.ArrayLike = (0.0, 0.0, 0.0)) -> None:
        """The target's angular velocity [rad/s] and acceleration [rad/s^2] in W (until the next target).

        ``set_target`` sets them to zero: call this after it.

        Raises:
            TaskSetupError: Not 3 finite numbers each.
        """
        self._vel_W[1] = world_vector(w, self.name, "target angular velocity [rad/s]")
        self._acc_W[1] = world_vector(alpha, self.name, "target angular acceleration [rad/s^2]")

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
        v_ref = np.concatenate([R_FW @ self._vel_W[0], R_FW @ self._vel_W[1]])
        a_ref = np.concatenate([R_FW @ self._acc_W[0], R_FW @ self._acc_W[1]])
        return a_ref + self._kp * self.compute_error(state) + self._kd * (v_ref - J @ state.v)

    stacked_acceleration = True

    def write_acceleration_terms(self, state: DynamicsState, J_t: np.ndarray, r_t: np.ndarray) -> None:
        """``J_F`` and ``kp log6(X_FT) + R_FW (a_ref + kd v_ref) - Jdot_F v`` (see the base class)."""
        if self._X_WT is None:
            raise self._no_target()
        fid = self.frame_id
        X_WF = state.frame_placements[fid]
        # log6(X_FT) = -log6(X_TF), X_TF = X_WT^-1 X_WF by one binding call
        np.multiply(pin.log6(self._X_WT.actInv(X_WF)).vector, -self._kp, out=r_t)
        ff = self._ff_W
        np.multiply(self._vel_W, self._kd, out=ff)
        ff += self._acc_W
        # R_FW u for both rows at once: (u^T R_WF)^T, i.e. the rows of ff R_WF ([linear; angular] in F)
        r_t += np.dot(ff, X_WF.rotation).reshape(6)
        r_t -= pin.getFrameAcceleration(state.model, state.data, fid, pin.LOCAL).vector
        J_t[:] = state.frame_jacobian(fid, pin.LOCAL)

    def residual(self, state: TaskState) -> TaskResidual:
        """Distance [m] and rotation angle [rad] to the target; a part with zero cost is left out."""
        X_TF = self._X_TF(state)
        position = float(np.linalg.norm(X_TF.translation)) if np.any(self.cost[:3] > 0.0) else None
        angle = float(np.linalg.norm(pin.log3(X_TF.rotation))) if np.any(self.cost[3:] > 0.0) else None
        return TaskResidual(position_m=position, orientation_rad=angle)
