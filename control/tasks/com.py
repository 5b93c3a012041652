"""The centre of mass: ``e = p_WC - p_target`` (3,) [m] in W.

Velocity level: ``J_e = J_com`` (3, nv). Acceleration level: the same Jacobian, drift
``Jdot_com v = dA_g[:3] v / m``, ``a_des = a_ref - kp e + kd (v_ref - J_com v)``, all in W.
A cost of 0 on an axis frees it (e.g. the height).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from mbctl.control.tasks.base import AccelerationGains, Task
from mbctl.control.tasks.frame import world_vector
from mbctl.control.tasks.residuals import TaskResidual
from mbctl.control.tasks.state import DynamicsState, TaskState


class ComTask(Task):
    """Centre of mass: ``e = p_WC - p_target`` (3,) [m], ``J = J_com`` (3, nv) (world frame).

    Attributes:
        v_ref: Target velocity (3,) [m/s] in W (acceleration level).
        a_ref: Target acceleration (3,) [m/s^2] in W (acceleration level).
    """

    def __init__(
        self,
        cost: npt.ArrayLike = 1.0,
        gain: float = 1.0,
        lm_damping: float = 0.0,
        name: str = "com",
        servo: AccelerationGains | None = None,
    ):
        """Create the task (set a target before solving).

        Args:
            cost: Weight(s) [cost]/[m], scalar or (3,) along world x, y, z (0 frees an axis).
            gain: Velocity level: fraction of the error corrected per step, in [0, 1].
            lm_damping: Velocity level: Levenberg-Marquardt scale [-].
            name: Report label.
            servo: Acceleration level: PD gains.

        Raises:
            TaskSetupError: Invalid cost, gain or damping.
        """
        super().__init__(name, 3, cost, gain, lm_damping, servo)
        self._target: np.ndarray | None = None
        self.v_ref = np.zeros(3)
        self.a_ref = np.zeros(3)

    def set_target(self, target_com: npt.ArrayLike, v: npt.ArrayLike = (0.0, 0.0, 0.0),
                   a: npt.ArrayLike = (0.0, 0.0, 0.0)) -> None:
        """Set the CoM target (3,) [m], its velocity [m/s] and acceleration [m/s^2], in W.

        Raises:
            TaskSetupError: Not finite (3,) vectors.
        """
        p = world_vector(target_com, self.name, "target position [m]")
        self.v_ref[:] = world_vector(v, self.name, "target velocity [m/s]")
        self.a_ref[:] = world_vector(a, self.name, "target acceleration [m/s^2]")
        self._target = p

    @property
    def target(self) -> np.ndarray:
        """The CoM target (3,) [m] in the world frame (a copy).

        Raises:
            TaskSetupError: No target set yet.
        """
        if self._target is None:
            raise self._no_target()
        return self._target.copy()

    def set_target_from_state(self, state: TaskState) -> None:
        """Set the target to the current CoM, at rest."""
        self.set_target(state.com())

    def compute_error(self, state: TaskState) -> np.ndarray:
        """``p_WC - p_target`` (3,) [m]."""
        if self._target is None:
            raise self._no_target()
        return state.com() - self._target

    def compute_jacobian(self, state: TaskState) -> np.ndarray:
        """``J_com`` (3, nv)."""
        return state.com_jacobian()

    def write_qp_rows(self, state: TaskState, W_t: np.ndarray, r_t: np.ndarray) -> float:
        """Fast path of ``Task.write_qp_rows`` (the same values)."""
        if self._target is None:
            raise self._no_target()
        col, _, neg_gain_cost, _ = self._weights()
        np.multiply(col, state.com_jacobian(), out=W_t)
        np.subtract(state.com(), self._target, out=r_t)
        r_t *= neg_gain_cost
        return self._lm_term(r_t)

    def write_velocity_rows(self, state: TaskState, J_out: np.ndarray, e_out: np.ndarray) -> None:
        """The active rows of ``(J_com, p_WC - p_target)`` (a zero-cost axis, e.g. z, is left out)."""
        if self._target is None:
            raise self._no_target()
        rows = self.active_index()
        J_out[:] = state.com_jacobian()[rows]
        np.subtract(state.com()[rows], self._target[rows], out=e_out)

    def jacobian_and_drift(self, state: DynamicsState) -> tuple[np.ndarray, np.ndarray]:
        """``(J_com, Jdot_com v)``."""
        return state.com_jacobian(), state.com_drift()

    def desired_acceleration(self, state: DynamicsState, J: np.ndarray) -> np.ndarray:
        """``a_ref - kp e + kd (v_ref - J_com v)`` (3,) [m/s^2] in W."""
        return self.a_ref - self._kp * self.compute_error(state) + self._kd * (self.v_ref - J @ state.v)

    stacked_acceleration = True

    def write_acceleration_terms(self, state: DynamicsState, J_t: np.ndarray, r_t: np.ndarray) -> None:
        """``J_com`` and ``kp (p* - p) + a_ref + kd v_ref - Jdot_com v`` (Task.write_acceleration_terms)."""
        if self._target is None:
            raise self._no_target()
        np.copyto(J_t, state.com_jacobian())
        # on plain floats: eight numpy calls on (3,) vectors cost ~4 us, these sums ~1 us with the reads
        kp, kd = self._kp, self._kd
        tx, ty, tz = self._target.tolist()
        cx, cy, cz = state.com().tolist()
        ax, ay, az = self.a_ref.tolist()
        vx, vy, vz = self.v_ref.tolist()
        dx, dy, dz = state.com_drift_xyz()
        r_t[:] = (kp * (tx - cx) + ax + kd * vx - dx, kp * (ty - cy) + ay + kd * vy - dy,
                  kp * (tz - cz) + az + kd * vz - dz)

    def residual(self, state: TaskState) -> TaskResidual:
        """Distance to the target over the weighted axes [m] (axes with zero cost are ignored)."""
        e = self.compute_error(state) * (self.cost > 0.0)
        return TaskResidual(position_m=float(np.linalg.norm(e)))
