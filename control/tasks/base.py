"""The task: an error ``e(q)`` with its Jacobian, and the least-squares rows it writes at each level.

One task object serves differential IK (velocity level) and whole-body inverse dynamics
(acceleration level); each task type is a module of this package and owns its error, its
Jacobians, its drift ``Jdot v`` and its rows.

Velocity level (differential IK, the mink formulation). ``J_e = de/dq`` on the configuration
manifold: ``e(q ⊕ dq) ≈ e(q) + J_e(q) dq`` with ``⊕`` = ``pin.integrate``. The task's rows are::

    W_t = diag(cost) J_e,   r_t = -gain diag(cost) e,   objective |W_t dq - r_t|^2 + mu |dq|^2

with the Levenberg-Marquardt term ``mu = lm_damping |r_t|^2``. Rows whose cost is zero add nothing
to the objective, so the IK stack asks each task for its active rows only
(:meth:`Task.write_velocity_rows`, unweighted) and weighs the whole stack in one product.

Acceleration level (inverse dynamics, the TSID formulation). A motion Jacobian ``J`` (k, nv) (for
frame poses the frame Jacobian J_F rather than the log-map Jacobian: the two agree at the target
and J_F has an exact drift), its drift ``Jdot v`` (k,), and a desired task acceleration from a PD
law on the error (:meth:`Task.desired_acceleration`, gains from :class:`AccelerationGains`)::

    W_t = diag(cost) J,   r_t = diag(cost) (a_des - Jdot v),   objective |W_t vdot - r_t|^2

Tasks without an acceleration form (the damping regulariser) raise ``TaskSetupError`` there.
"""

from __future__ import annotations

import abc
import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from mbctl.control.exceptions import TaskSetupError
from mbctl.control.tasks.residuals import TaskResidual
from mbctl.control.tasks.state import DynamicsState, TaskState
from mbctl.robots.indexing import as_slice


@dataclass(frozen=True)
class AccelerationGains:
    """PD gains of a task's desired acceleration, from a natural frequency and a damping ratio.

    The loop is already normalised by M(q), so ``kp = omega^2`` [1/s^2] and ``kd = 2 zeta omega``
    [1/s] give the task error the dynamics ``e'' + kd e' + kp e = 0``.

    Attributes:
        omega_rad_s: Closed-loop natural frequency [rad/s] (>= 0).
        zeta: Damping ratio [-] (>= 0).
    """

    omega_rad_s: float = 10.0
    zeta: float = 1.0

    def __post_init__(self) -> None:
        for name in ("omega_rad_s", "zeta"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise TaskSetupError(f"AccelerationGains.{name} must be finite and >= 0; got {value!r}")

    @property
    def kp(self) -> float:
        """Stiffness ``omega^2`` [1/s^2]."""
        return self.omega_rad_s**2

    @property
    def kd(self) -> float:
        """Damping ``2 zeta omega`` [1/s]."""
        return 2.0 * self.zeta * self.omega_rad_s


def cost_vector(cost: npt.ArrayLike, k: int, owner: str, what: str = "cost") -> np.ndarray:
    """``cost`` as a read-only (k,) vector of weights (a scalar is broadcast).

    Raises:
        TaskSetupError: A negative, non-finite or misshaped cost (the message names ``what``).
    """
    arr = np.atleast_1d(np.asarray(cost, dtype=float))
    if arr.shape == (1,):
        arr = np.full(k, arr[0])
    if arr.shape != (k,) or not np.all(np.isfinite(arr)) or np.any(arr < 0.0):
        raise TaskSetupError(f"{owner} {what} must be a non-negative scalar or a vector of shape ({k},); "
                             f"got {np.asarray(cost).tolist()!r}")
    arr = arr.copy()
    arr.setflags(write=False)
    return arr


#: Bumped whenever any task's cost, gain or LM damping changes, so that stacks built on cached
#: weights (:class:`~mbctl.control.tasks.stack.TaskStack`) know to re-read them (one int to compare
#: per solve instead of every task's weights).
_WEIGHTS_EPOCH = [0]


def weights_epoch() -> int:
    """A counter that changes whenever any task's cost, gain or LM damping changes."""
    return _WEIGHTS_EPOCH[0]


def dot_into(a: np.ndarray, b: np.ndarray, out: np.ndarray) -> None:
    """``out[:] = a @ b`` for the small products of the velocity rows.

    ``np.dot`` with ``out`` costs ~0.5 us against ``np.matmul``'s ~1.5 us on a (6, 6) x (6, nv)
    product (the same BLAS call); it takes only a C-contiguous ``out``, so any other is written
    by a copy.
    """
    try:
        np.dot(a, b, out=out)
    except ValueError:  # out not C-contiguous (or misshaped: the copy then says so)
        out[:] = a @ b


def floating_dofs(model: pin.Model) -> np.ndarray:
    """Tangent indices of the model's free-flyer joints (left out of posture and damping)."""
    idx: list[int] = []
    for j in range(1, model.njoints):
        if model.joints[j].shortname() == "JointModelFreeFlyer":
            start = model.joints[j].idx_v
            idx.extend(range(start, start + 6))
    return np.array(idx, dtype=int)


class Task(abc.ABC):
    """A least-squares objective on an error ``e(q)`` (k,), at the velocity or acceleration level.

    Subclasses implement ``compute_error``, ``compute_jacobian`` and ``residual``; tasks with an
    acceleration form also ``jacobian_and_drift`` and ``desired_acceleration``.

    Attributes:
        name: Label used in residual reports.
        k: Task dimension.
        gain: Velocity level: fraction ``alpha`` in [0, 1] of the error corrected per step.
        lm_damping: Velocity level: Levenberg-Marquardt scale [-] (>= 0).
        servo: Acceleration level: the PD gains of the desired acceleration.
        regularizing: True for tasks that never reach zero error (posture, damping); their
            residuals never gate convergence.
    """

    regularizing: bool = False

    def __init__(self, name: str, k: int, cost: npt.ArrayLike, gain: float = 1.0, lm_damping: float = 0.0,
                 servo: AccelerationGains | None = None):
        """Validate and store the common parameters.

        Raises:
            TaskSetupError: A negative cost, a gain outside [0, 1] or a negative lm_damping.
        """
        self.name = name
        self.k = k
        self.gain = gain
        self.lm_damping = lm_damping
        self.servo = servo if servo is not None else AccelerationGains()
        self._set_cost_vector(cost_vector(cost, k, name))

    @property
    def gain(self) -> float:
        """Velocity level: fraction ``alpha`` in [0, 1] of the error corrected per step."""
        return self._gain

    @gain.setter
    def gain(self, value: float) -> None:
        if not 0.0 <= value <= 1.0:
            raise TaskSetupError(f"{self.name}: gain must be in [0, 1]; got {value!r}")
        self._gain = float(value)
        _WEIGHTS_EPOCH[0] += 1

    @property
    def lm_damping(self) -> float:
        """Velocity level: Levenberg-Marquardt scale [-] (>= 0)."""
        return self._lm_damping

    @lm_damping.setter
    def lm_damping(self, value: float) -> None:
        if not (math.isfinite(value) and value >= 0.0):
            raise TaskSetupError(f"{self.name}: lm_damping must be >= 0; got {value!r}")
        self._lm_damping = float(value)
        _WEIGHTS_EPOCH[0] += 1

    @property
    def servo(self) -> AccelerationGains:
        """Acceleration level: the PD gains (assignable; ``kp`` and ``kd`` are cached from them)."""
        return self._servo

    @servo.setter
    def servo(self, gains: AccelerationGains) -> None:
        self._servo = gains
        self._kp, self._kd = gains.kp, gains.kd
        _WEIGHTS_EPOCH[0] += 1  # the stacks' damping rows hold kd

    # ------------------------------------------------------------------ weights and targets
    @property
    def cost(self) -> np.ndarray:
        """Weights (k,) [cost]/[task unit], read-only."""
        return self._cost

    def set_cost(self, cost: npt.ArrayLike) -> None:
        """Replace the weights (scalar or (k,)).

        Raises:
            TaskSetupError: A negative or misshaped cost.
        """
        self._set_cost_vector(cost_vector(cost, self.k, self.name))
        _WEIGHTS_EPOCH[0] += 1

    def _set_cost_vector(self, cost: np.ndarray) -> None:
        """Store a checked cost and the active rows it implies (read on every IK step)."""
        self._cost = cost
        rows = np.flatnonzero(cost > 0.0)
        rows.setflags(write=False)
        self._rows = rows
        self._index = as_slice(rows)
        #: Every row active: the hot paths then index nothing.
        self._all_active = len(rows) == self.k

    def active_rows(self) -> np.ndarray:
        """Indices of the rows with a non-zero cost (read-only; the only rows the IK stacks)."""
        return self._rows

    def active_index(self) -> slice | np.ndarray:
        """The active rows as a slice when they are contiguous (indexing is then a view)."""
        return self._index

    def set_target_from_state(self, state: TaskState) -> None:  # noqa: B027 - optional hook
        """Set the target to the current value at ``state``; tasks without a target ignore it."""

    def _no_target(self) -> TaskSetupError:
        """The error for a task asked for its error before ``set_target``."""
        return TaskSetupError(f"{self.name}: no target set; call set_target first.")

    def _weights(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(cost[:, None], -cost[:, None], -gain cost, gain cost)``, cached.

        The cache is rebuilt when ``cost`` (replaced by ``set_cost``) or ``gain`` change.
        """
        cached = self.__dict__.get("_weights_cache")
        if cached is None or cached[0] is not self._cost or cached[1] != self.gain:
            col = self._cost[:, None].copy()
            gain_cost = self.gain * self._cost
            cached = (self._cost, self.gain, col, -col, -gain_cost, gain_cost)
            self.__dict__["_weights_cache"] = cached
        return cached[2], cached[3], cached[4], cached[5]

    # ------------------------------------------------------------------ velocity level
    @abc.abstractmethod
    def compute_error(self, state: TaskState) -> np.ndarray:
        """Task error ``e(q)`` (k,)."""

    @abc.abstractmethod
    def compute_jacobian(self, state: TaskState) -> np.ndarray:
        """Task Jacobian ``de/dq`` (k, nv) on the manifold."""

    def error_and_jacobian(self, state: TaskState) -> tuple[np.ndarray, np.ndarray]:
        """``(e, J_e)`` together (override to share intermediate results)."""
        return self.compute_error(state), self.compute_jacobian(state)

    def write_qp_rows(self, state: TaskState, W_t: np.ndarray, r_t: np.ndarray) -> float:
        """Fill this task's velocity-level rows in place and return its LM term.

        Args:
            state: Kinematic state.
            W_t: (k, nv) output, ``diag(cost) J_e``.
            r_t: (k,) output, ``-gain diag(cost) e``.

        Returns:
            ``mu = lm_damping |r_t|^2`` [cost^2].
        """
        e, J = self.error_and_jacobian(state)
        col, _, neg_gain_cost, _ = self._weights()
        np.multiply(col, J, out=W_t)
        np.multiply(neg_gain_cost, e, out=r_t)
        return self._lm_term(r_t)

    def write_velocity_rows(self, state: TaskState, J_out: np.ndarray, e_out: np.ndarray) -> None:
        """Write the unweighted rows ``J_e[a]`` (len(a), nv) and ``e[a]`` (len(a),), ``a = active_rows()``.

        A task may write ``(-J_e[a], -e[a])`` instead (both negated: the least squares, and so the
        QP, are the same); the stack weighs every task's rows in one product afterwards.
        """
        e, J = self.error_and_jacobian(state)
        rows = self.active_index()
        J_out[:] = J[rows]
        e_out[:] = e[rows]

    def _lm_term(self, r_t: np.ndarray) -> float:
        """``mu = lm_damping |r_t|^2`` [cost^2] for the rows ``r_t`` (k,) (0 without LM damping)."""
        return self.lm_damping * float(r_t @ r_t) if self.lm_damping > 0.0 else 0.0

    # ------------------------------------------------------------------ acceleration level
    def jacobian_and_drift(self, state: DynamicsState) -> tuple[np.ndarray, np.ndarray]:
        """``(J (k, nv), Jdot v (k,))`` at ``state`` (tested against finite differences).

        Raises:
            TaskSetupError: The task has no acceleration-level form.
        """
        raise TaskSetupError(f"{self.name}: {type(self).__name__} has no acceleration-level form "
                             "(use it in differential IK only)")

    def desired_acceleration(self, state: DynamicsState, J: np.ndarray) -> np.ndarray:
        """``a_des`` (k,): the PD law on the error plus the reference's feed-forward.

        Raises:
            TaskSetupError: The task has no acceleration-level form.
        """
        raise TaskSetupError(f"{self.name}: {type(self).__name__} has no acceleration-level form "
                             "(use it in differential IK only)")

    def _acceleration_scratch(self) -> np.ndarray:
        """A (k,) buffer of this task's for the temporaries of its acceleration rows (made on first use)."""
        buf = self.__dict__.get("_acceleration_buffer")
        if buf is None:
            buf = self.__dict__["_acceleration_buffer"] = np.zeros(self.k)
        return buf

    def write_acceleration_rows(self, state: DynamicsState, W_t: np.ndarray, r_t: np.ndarray) -> None:
        """Fill this task's acceleration-level rows in place.

        Args:
            state: Dynamics state.
            W_t: (k, nv) output, ``diag(cost) J``.
            r_t: (k,) output, ``diag(cost) (a_des - Jdot v)``.
        """
        J, drift = self.jacobian_and_drift(state)
        col = self._weights()[0]
        np.multiply(col, J, out=W_t)
        np.subtract(self.desired_acceleration(state, J), drift, out=r_t)
        r_t *= self._cost

    #: Whether the task writes :meth:`write_acceleration_terms` (the stack then weighs and damps
    #: every such task's rows in one product each); else the stack calls ``write_acceleration_rows``.
    stacked_acceleration: bool = False

    def constant_acceleration_jacobian(self, state: DynamicsState) -> np.ndarray | None:
        """``J`` (k, nv) when it is the same at every state (written once by the stack), else None."""
        return None

    def write_acceleration_terms(self, state: DynamicsState, J_t: np.ndarray, r_t: np.ndarray) -> None:
        """Write ``J`` (k, nv) (unless constant) and ``a_des + kd J v - Jdot v`` (k,), both unweighted.

        The stack (:class:`~mbctl.control.tasks.stack.TaskStack`) then forms the rows of
        :meth:`write_acceleration_rows` for every such task at once: ``W_t = diag(cost) J``,
        ``r_t = diag(cost) (terms - kd J v)``. Tasks with ``stacked_acceleration`` override it.

        Raises:
            TaskSetupError: The task has no stacked form.
        """
        raise TaskSetupError(f"{self.name}: {type(self).__name__} writes its acceleration rows whole "
                             "(write_acceleration_rows)")

    # ------------------------------------------------------------------ reports
    @abc.abstractmethod
    def residual(self, state: TaskState) -> TaskResidual:
        """How far the task is from its target at ``state`` (units in the fields)."""
