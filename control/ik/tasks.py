"""Differential-IK tasks on Pinocchio Jacobians (the mink design, on Pinocchio).

A task has an error ``e(q)`` (k,) that IK drives to zero and its Jacobian ``J(q) = de/dq`` (k, nv)
on the configuration manifold: ``e(q ⊕ dq) ≈ e(q) + J(q) dq`` with ``⊕`` = ``pin.integrate``.
Its QP contribution is ``|| W (J dq + alpha e) ||^2`` with ``W = diag(cost)``, plus the
Levenberg-Marquardt term ``mu |dq|^2`` with ``mu = lm_damping |W alpha e|^2``.

Notation (Drake monograms): W world, F the task frame, T the target frame, C the centre of mass.
``X_TF = X_WT^-1 X_WF``; ``J_F`` is F's body Jacobian (twist of F in F, [v; w]).

Pose errors follow mink exactly (so both solvers build the same QP): ``e = log6(X_FT) =
-log6(X_TF)``, ``J = -Jlog6(X_TF) J_F``; the orientation task keeps the rotation rows.
"""

from __future__ import annotations

import abc
from collections.abc import Mapping

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from mbctl.control.exceptions import IKSetupError
from mbctl.control.ik.state import IKState
from mbctl.robots.exceptions import UnknownNameError


def _pin_model(state_or_model: IKState | pin.Model) -> pin.Model:
    return state_or_model.model if isinstance(state_or_model, IKState) else state_or_model


def _cost_vector(cost: npt.ArrayLike, k: int, owner: str, what: str = "cost") -> np.ndarray:
    arr = np.atleast_1d(np.asarray(cost, dtype=float))
    if arr.shape == (1,):
        arr = np.full(k, arr[0])
    if arr.shape != (k,) or not np.all(np.isfinite(arr)) or np.any(arr < 0.0):
        raise IKSetupError(
            f"{owner} {what} must be a non-negative scalar or a vector of shape ({k},); "
            f"got {np.asarray(cost).tolist()!r}"
        )
    return arr


class Task(abc.ABC):
    """A least-squares IK objective ``|| diag(cost) (J dq + gain e) ||^2``.

    Subclasses implement ``compute_error`` and ``compute_jacobian`` (and may override
    ``error_and_jacobian`` to share work between them).

    Attributes:
        name: Label used in residual reports.
        k: Task dimension.
        cost: Weights (k,) in [cost]/[task unit], read-only.
        gain: Fraction ``alpha`` in [0, 1] of the error corrected per step (1 = dead-beat).
        lm_damping: Levenberg-Marquardt scale [-] (>= 0), grows the diagonal with the error.
        regularizing: True for tasks that never reach zero error (posture, damping); they are
            left out of convergence checks.
    """

    regularizing: bool = False

    def __init__(self, name: str, k: int, cost: npt.ArrayLike, gain: float, lm_damping: float):
        """Validate and store the common parameters.

        Raises:
            IKSetupError: A negative cost, a gain outside [0, 1] or a negative lm_damping.
        """
        if not 0.0 <= gain <= 1.0:
            raise IKSetupError(f"{name}: gain must be in [0, 1]; got {gain!r}")
        if not (np.isfinite(lm_damping) and lm_damping >= 0.0):
            raise IKSetupError(f"{name}: lm_damping must be >= 0; got {lm_damping!r}")
        self.name = name
        self.k = k
        self.gain = float(gain)
        self.lm_damping = float(lm_damping)
        self._cost = _cost_vector(cost, k, name)
        self._cost.setflags(write=False)

    def set_target_from_state(self, state: IKState) -> None:  # noqa: B027 - optional hook
        """Set the target to the current value at ``state``; tasks without a target ignore it."""

    @property
    def cost(self) -> np.ndarray:
        """Weights (k,), read-only."""
        return self._cost

    def set_cost(self, cost: npt.ArrayLike) -> None:
        """Replace the weights (scalar or (k,)).

        Raises:
            IKSetupError: A negative or misshaped cost.
        """
        new = _cost_vector(cost, self.k, self.name)
        new.setflags(write=False)
        self._cost = new

    @abc.abstractmethod
    def compute_error(self, state: IKState) -> np.ndarray:
        """Task error ``e(q)`` (k,)."""

    @abc.abstractmethod
    def compute_jacobian(self, state: IKState) -> np.ndarray:
        """Task Jacobian ``de/dq`` (k, nv) on the manifold."""

    def error_and_jacobian(self, state: IKState) -> tuple[np.ndarray, np.ndarray]:
        """``(e, J)`` together (override to share intermediate results)."""
        return self.compute_error(state), self.compute_jacobian(state)

    def residuals(self, state: IKState) -> dict[str, float]:
        """Unweighted error norms for reports, by quantity (with units in the key)."""
        return {"error": float(np.linalg.norm(self.compute_error(state)))}

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

    def write_qp_rows(self, state: IKState, W_t: np.ndarray, r_t: np.ndarray) -> float:
        """Fill this task's least-squares rows in place and return its LM term.

        Args:
            state: Kinematic state.
            W_t: (k, nv) output, ``diag(cost) J``.
            r_t: (k,) output, ``-gain diag(cost) e``.

        Returns:
            ``mu = lm_damping |r_t|^2`` [cost^2].
        """
        e, J = self.error_and_jacobian(state)
        col, _, neg_gain_cost, _ = self._weights()
        np.multiply(col, J, out=W_t)
        np.multiply(neg_gain_cost, e, out=r_t)
        return self._lm_term(r_t)

    def _no_target(self) -> IKSetupError:
        """The error for a task asked for its error before ``set_target``."""
        return IKSetupError(f"{self.name}: no target set; call set_target first.")

    def _lm_term(self, r_t: np.ndarray) -> float:
        """``mu = lm_damping |r_t|^2`` [cost^2] for the rows ``r_t`` (k,) (0 without LM damping)."""
        return self.lm_damping * float(r_t @ r_t) if self.lm_damping > 0.0 else 0.0


# ---------------------------------------------------------------------- frame tasks
class _FrameTask(Task):
    """A task on the pose of one Pinocchio frame F against a target pose ``X_WT``."""

    def __init__(
        self,
        name: str,
        frame: str,
        state_or_model: IKState | pin.Model,
        k: int,
        cost: npt.ArrayLike,
        gain: float,
        lm_damping: float,
    ):
        super().__init__(name, k, cost, gain, lm_damping)
        model = _pin_model(state_or_model)
        if not model.existFrame(frame):
            raise UnknownNameError("frame", frame, [f.name for f in model.frames])
        self.frame = frame
        self.frame_id = model.getFrameId(frame)
        self._X_WT: pin.SE3 | None = None
        self._X_TW: pin.SE3 | None = None

    def set_target(self, transform_target_to_world: pin.SE3) -> None:
        """Set the target pose ``X_WT``."""
        self._X_WT = pin.SE3(transform_target_to_world)
        self._X_TW = self._X_WT.inverse()

    def set_target_from_state(self, state: IKState) -> None:
        """Set the target to the frame's current pose."""
        self.set_target(state.frame_pose(self.frame_id))

    @property
    def transform_target_to_world(self) -> pin.SE3:
        """Target pose ``X_WT``.

        Raises:
            IKSetupError: No target set yet.
        """
        if self._X_WT is None:
            raise self._no_target()
        return self._X_WT

    def _X_TF(self, state: IKState) -> pin.SE3:
        """``X_TF = X_WT^-1 X_WF`` at ``state``.

        Raises:
            IKSetupError: No target set yet.
        """
        if self._X_TW is None:
            raise self._no_target()
        return self._X_TW * state.oMf[self.frame_id]


class FramePoseTask(_FrameTask):
    """Pose of a frame: ``e = log6(X_FT)`` (6,) [m, rad] in F, ``J = -Jlog6(X_TF) J_F``.

    Equal to mink's ``FrameTask``; cost is (position [3], orientation [3]).
    """

    def __init__(
        self,
        frame: str,
        model: IKState | pin.Model,
        position_cost: npt.ArrayLike = 1.0,
        orientation_cost: npt.ArrayLike = 1.0,
        gain: float = 1.0,
        lm_damping: float = 0.0,
        name: str | None = None,
    ):
        """Create the task (set a target before solving).

        Args:
            frame: Pinocchio frame name (body, site, operational frame).
            model: Pinocchio model or IK state.
            position_cost: Weight(s) on the translation error [cost]/[m], scalar or (3,).
            orientation_cost: Weight(s) on the rotation error [cost]/[rad], scalar or (3,).
            gain: Fraction of the error corrected per step, in [0, 1].
            lm_damping: Levenberg-Marquardt scale [-].
            name: Report label (default: "<frame> pose").

        Raises:
            UnknownNameError: No frame called ``frame``.
            IKSetupError: Invalid costs, gain or damping.
        """
        pos = _cost_vector(position_cost, 3, frame, "position_cost")
        rot = _cost_vector(orientation_cost, 3, frame, "orientation_cost")
        super().__init__(
            name or f"{frame} pose", frame, model, 6, np.concatenate([pos, rot]), gain, lm_damping
        )

    def compute_error(self, state: IKState) -> np.ndarray:
        """``log6(X_FT)`` (6,) [m, rad]: the twist from F to the target, in F."""
        return -pin.log6(self._X_TF(state)).vector

    def compute_jacobian(self, state: IKState) -> np.ndarray:
        """``-Jlog6(X_TF) J_F`` (6, nv)."""
        return self.error_and_jacobian(state)[1]

    def error_and_jacobian(self, state: IKState) -> tuple[np.ndarray, np.ndarray]:
        """Both, from one ``X_TF``."""
        X_TF = self._X_TF(state)
        J = pin.Jlog6(X_TF) @ state.frame_jacobian_local(self.frame_id)
        return -pin.log6(X_TF).vector, np.negative(J, out=J)

    def write_qp_rows(self, state: IKState, W_t: np.ndarray, r_t: np.ndarray) -> float:
        """Fast path of ``Task.write_qp_rows`` (the hot path of ``DiffIK``): same values.

        ``W_t = -diag(cost) Jlog6(X_TF) J_F`` and ``r_t = gain diag(cost) log6(X_TF)``, written
        in place with no temporaries for the negations.
        """
        X_TF = self._X_TF(state)
        J_F = state.frame_jacobian_local(self.frame_id)
        _, neg_col, _, gain_cost = self._weights()
        np.matmul(pin.Jlog6(X_TF), J_F, out=W_t)
        W_t *= neg_col
        np.multiply(gain_cost, pin.log6(X_TF).vector, out=r_t)
        return self._lm_term(r_t)

    def residuals(self, state: IKState) -> dict[str, float]:
        """Distance [m] and rotation angle [rad] to the target; a part with zero cost is omitted."""
        X_TF = self._X_TF(state)
        out = {}
        if np.any(self.cost[:3] > 0.0):
            out["position [m]"] = float(np.linalg.norm(X_TF.translation))
        if np.any(self.cost[3:] > 0.0):
            out["orientation [rad]"] = float(np.linalg.norm(pin.log3(X_TF.rotation)))
        return out


class _FrameAxesTask(_FrameTask):
    """A 3-dimensional frame task (position or orientation); ``kind`` names it in reports."""

    kind: str

    def __init__(
        self,
        frame: str,
        model: IKState | pin.Model,
        cost: npt.ArrayLike = 1.0,
        gain: float = 1.0,
        lm_damping: float = 0.0,
        name: str | None = None,
    ):
        """Create the task (set a target before solving).

        Args:
            frame: Pinocchio frame name.
            model: Pinocchio model or IK state.
            cost: Weight(s), scalar or (3,): [cost]/[m] along world x, y, z for a position
                task, [cost]/[rad] about the frame's axes for an orientation task.
            gain: Fraction of the error corrected per step, in [0, 1].
            lm_damping: Levenberg-Marquardt scale [-].
            name: Report label (default: "<frame> position" or "<frame> orientation").

        Raises:
            UnknownNameError: No frame called ``frame``.
            IKSetupError: Invalid cost, gain or damping.
        """
        super().__init__(name or f"{frame} {self.kind}", frame, model, 3, cost, gain, lm_damping)


class FramePositionTask(_FrameAxesTask):
    """Position of a frame origin: ``e = p_WF - p_WT`` (3,) [m] in W, ``J = R_WF J_F[:3]``."""

    kind = "position"

    def set_target(self, transform_target_to_world: pin.SE3 | npt.ArrayLike) -> None:
        """Set the target position ``p_WT`` (3,) [m] (an SE3's translation is used).

        Raises:
            IKSetupError: Not a finite (3,) position.
        """
        if isinstance(transform_target_to_world, pin.SE3):
            p = transform_target_to_world.translation.copy()
        else:
            p = np.asarray(transform_target_to_world, dtype=float).copy()
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise IKSetupError(f"{self.name}: target must be a finite (3,) position [m]; got {p!r}")
        super().set_target(pin.SE3(np.eye(3), p))

    def compute_error(self, state: IKState) -> np.ndarray:
        """``p_WF - p_WT`` (3,) [m]."""
        p_WT = self.transform_target_to_world.translation
        return state.frame_pose(self.frame_id).translation - p_WT

    def compute_jacobian(self, state: IKState) -> np.ndarray:
        """``R_WF J_F[:3]`` (3, nv)."""
        R_WF = state.frame_pose(self.frame_id).rotation
        return R_WF @ state.frame_jacobian_local(self.frame_id)[:3]

    def residuals(self, state: IKState) -> dict[str, float]:
        """Distance to the target [m]."""
        return {"position [m]": float(np.linalg.norm(self.compute_error(state)))}


class FrameOrientationTask(_FrameAxesTask):
    """Orientation of a frame: ``e = log3(R_FT)`` (3,) [rad], ``J = -Jlog3(R_TF) J_F[3:]``."""

    kind = "orientation"

    def compute_error(self, state: IKState) -> np.ndarray:
        """``log3(R_FT) = -log3(R_TF)`` (3,) [rad]."""
        return -pin.log3(self._X_TF(state).rotation)

    def compute_jacobian(self, state: IKState) -> np.ndarray:
        """``-Jlog3(R_TF) J_F[3:]`` (3, nv)."""
        return self.error_and_jacobian(state)[1]

    def error_and_jacobian(self, state: IKState) -> tuple[np.ndarray, np.ndarray]:
        """Both, from one ``R_TF``."""
        R_TF = self._X_TF(state).rotation
        J_F = state.frame_jacobian_local(self.frame_id)
        J = pin.Jlog3(R_TF) @ J_F[3:]
        return -pin.log3(R_TF), np.negative(J, out=J)

    def residuals(self, state: IKState) -> dict[str, float]:
        """Rotation angle to the target [rad]."""
        return {"orientation [rad]": float(np.linalg.norm(self.compute_error(state)))}


# ---------------------------------------------------------------------- whole-body tasks
class ComTask(Task):
    """Centre of mass: ``e = p_WC - p_target`` (3,) [m], ``J = J_com`` (3, nv) (world frame)."""

    def __init__(
        self,
        cost: npt.ArrayLike = 1.0,
        gain: float = 1.0,
        lm_damping: float = 0.0,
        name: str = "com",
    ):
        """Create the task (set a target before solving).

        Args:
            cost: Weight(s) [cost]/[m], scalar or (3,) along world x, y, z (0 frees an axis).
            gain: Fraction of the error corrected per step, in [0, 1].
            lm_damping: Levenberg-Marquardt scale [-].
            name: Report label.

        Raises:
            IKSetupError: Invalid cost, gain or damping.
        """
        super().__init__(name, 3, cost, gain, lm_damping)
        self._target: np.ndarray | None = None

    def set_target(self, target_com: npt.ArrayLike) -> None:
        """Set the CoM target (3,) [m] in the world frame.

        Raises:
            IKSetupError: Not a finite (3,) vector.
        """
        p = np.asarray(target_com, dtype=float).copy()
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise IKSetupError(f"{self.name}: target must be a finite (3,) position [m]; got {p!r}")
        self._target = p

    @property
    def target(self) -> np.ndarray:
        """The CoM target (3,) [m] in the world frame (a copy).

        Raises:
            IKSetupError: No target set yet.
        """
        if self._target is None:
            raise self._no_target()
        return self._target.copy()

    def set_target_from_state(self, state: IKState) -> None:
        """Set the target to the current CoM."""
        self.set_target(state.com())

    def compute_error(self, state: IKState) -> np.ndarray:
        """``p_WC - p_target`` (3,) [m]."""
        if self._target is None:
            raise self._no_target()
        return state.com() - self._target

    def compute_jacobian(self, state: IKState) -> np.ndarray:
        """``J_com`` (3, nv)."""
        return state.com_jacobian()

    def write_qp_rows(self, state: IKState, W_t: np.ndarray, r_t: np.ndarray) -> float:
        """Fast path of ``Task.write_qp_rows`` (same values)."""
        if self._target is None:
            raise self._no_target()
        col, _, neg_gain_cost, _ = self._weights()
        np.multiply(col, state.com_jacobian(), out=W_t)
        np.subtract(state.data.com[0], self._target, out=r_t)
        r_t *= neg_gain_cost
        return self._lm_term(r_t)

    def residuals(self, state: IKState) -> dict[str, float]:
        """Weighted-axes distance to the target [m] (axes with zero cost are ignored)."""
        e = self.compute_error(state) * (self.cost > 0.0)
        return {"position [m]": float(np.linalg.norm(e))}


def _floating_dofs(model: pin.Model) -> np.ndarray:
    """Tangent indices of free-flyer joints (left out of posture and damping)."""
    idx: list[int] = []
    for j in range(1, model.njoints):
        if model.joints[j].shortname() == "JointModelFreeFlyer":
            start = model.joints[j].idx_v
            idx.extend(range(start, start + 6))
    return np.array(idx, dtype=int)


def _as_slice_or_array(idx: np.ndarray) -> slice | np.ndarray | None:
    """None when empty, a slice when contiguous (cheap to assign), else the index array."""
    if idx.size == 0:
        return None
    if np.array_equal(idx, np.arange(idx[0], idx[0] + idx.size)):
        return slice(int(idx[0]), int(idx[0]) + idx.size)
    return idx


class DiagonalTask(Task):
    """A task whose Jacobian is a constant 0/1 diagonal ``diag(mask)`` (nv, nv).

    ``DiffIK`` adds such tasks straight onto the diagonal of H (``cost^2 mask``) and into c
    (``gain cost^2 mask e``) instead of stacking nv more rows into the least-squares matrix.

    Attributes:
        mask: (nv,) 1.0 where the task acts, 0.0 elsewhere (read-only).
        is_diagonal: Whether the Jacobian really is ``diag(mask)`` for this model (the solver
            takes the diagonal shortcut only then).
    """

    is_diagonal: bool = True

    def __init__(
        self, name: str, model: IKState | pin.Model, cost: npt.ArrayLike, gain: float,
        lm_damping: float,
    ):
        self.model = _pin_model(model)
        super().__init__(name, self.model.nv, cost, gain, lm_damping)
        self._free_idx = _floating_dofs(self.model)
        self._jacobian = np.eye(self.model.nv)
        self._jacobian[self._free_idx, self._free_idx] = 0.0
        self._jacobian.setflags(write=False)
        self.mask = np.diag(self._jacobian).copy()
        self.mask.setflags(write=False)


class PostureTask(DiagonalTask):
    """Joint posture: ``e = q ⊖ q_target`` (nv,) (``pin.difference``), ``J = de/dq`` (nv, nv).

    Free-flyer rows are zero (the base is not pulled to a posture), as in mink. For 1-dof
    joints ``J`` is the identity; for ball joints it is the exact ``pin.dDifference`` block
    (mink uses the identity there, a first-order approximation).
    """

    regularizing = True

    def __init__(
        self,
        model: IKState | pin.Model,
        cost: npt.ArrayLike = 1e-2,
        gain: float = 1.0,
        lm_damping: float = 0.0,
        name: str = "posture",
    ):
        """Create the task (set a target before solving).

        Args:
            model: Pinocchio model or IK state.
            cost: Weight(s) [cost]/[rad], scalar or (nv,).
            gain: Fraction of the error corrected per step, in [0, 1].
            lm_damping: Levenberg-Marquardt scale [-].
            name: Report label.

        Raises:
            IKSetupError: Invalid cost, gain or damping.
        """
        super().__init__(name, model, cost, gain, lm_damping)
        self._free = _as_slice_or_array(self._free_idx)
        self.is_diagonal = all(
            joint.nv == 1 or joint.shortname() == "JointModelFreeFlyer"
            for joint in list(self.model.joints)[1:]
        )
        self._target: np.ndarray | None = None

    def set_target(self, target_q: npt.ArrayLike) -> None:
        """Set the target configuration (nq,), Pinocchio convention.

        Raises:
            IKSetupError: Wrong shape or non-finite entries.
        """
        q = np.asarray(target_q, dtype=float).copy()
        if q.shape != (self.model.nq,) or not np.all(np.isfinite(q)):
            raise IKSetupError(
                f"{self.name}: target must be a finite ({self.model.nq},) configuration; "
                f"got shape {q.shape}"
            )
        self._target = q

    def set_target_from_state(self, state: IKState) -> None:
        """Set the target to the current configuration."""
        self.set_target(state.q)

    def compute_error(self, state: IKState) -> np.ndarray:
        """``q ⊖ q_target`` (nv,), free-flyer entries zeroed."""
        if self._target is None:
            raise self._no_target()
        e = pin.difference(self.model, self._target, state.q)
        if self._free is not None:
            e[self._free] = 0.0
        return e

    def compute_jacobian(self, state: IKState) -> np.ndarray:
        """``d(q ⊖ q_target)/dq`` (nv, nv), free-flyer rows zeroed.

        The identity (constant, read-only) unless the model has ball joints.
        """
        if self.is_diagonal:
            return self._jacobian
        if self._target is None:
            raise self._no_target()
        J = pin.dDifference(self.model, self._target, state.q, pin.ArgumentPosition.ARG1)
        J[self._free_idx, :] = 0.0
        return J


class DampingTask(DiagonalTask):
    """Minimum-motion regulariser: ``e = 0``, ``J = I`` (free-flyer rows zero), gain 0.

    Adds ``sum_i cost_i^2 dq_i^2`` to the objective (mink's ``DampingTask``).
    """

    regularizing = True

    def __init__(self, model: IKState | pin.Model, cost: npt.ArrayLike = 1e-3, name: str = "damping"):
        """Create the task.

        Args:
            model: Pinocchio model or IK state.
            cost: Weight(s) [cost]/[rad], scalar or (nv,).
            name: Report label.

        Raises:
            IKSetupError: Invalid cost.
        """
        super().__init__(name, model, cost, 0.0, 0.0)
        self._zero = np.zeros(self.model.nv)
        self._zero.setflags(write=False)

    def compute_error(self, state: IKState) -> np.ndarray:
        """Zero (nv,)."""
        return self._zero

    def compute_jacobian(self, state: IKState) -> np.ndarray:
        """Identity (nv, nv) with free-flyer rows zeroed."""
        return self._jacobian


def task_residuals(tasks: Mapping[str, Task] | list[Task], state: IKState) -> dict[str, dict]:
    """Residual norms of each task at ``state``, keyed by task name."""
    items = tasks.values() if isinstance(tasks, Mapping) else tasks
    return {t.name: t.residuals(state) for t in items}
