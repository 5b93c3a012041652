"""The tasks' weighted least squares as a QP objective, assembled once for IK and for inverse dynamics.

Every task writes rows ``W_t x ≈ r_t`` (velocity level: ``x = dq``; acceleration level:
``x = vdot``; see :mod:`mbctl.control.tasks.base`). Stacked, they give::

    1/2 |W x - r|^2  =  1/2 x^T H x + c^T x + const,   H = W^T W,   c = -W^T r

Diagonal tasks (posture, damping; :mod:`mbctl.control.tasks.diagonal`) go straight onto H's
diagonal (``cost^2 mask``) and into c instead of adding nv rows each. The row buffers are allocated
once per task set and reused every cycle; the two QPs (differential IK, whole-body inverse
dynamics) call this one assembly.

At the velocity level the stack keeps only the rows with a non-zero cost (a hand's orientation
rows, the CoM's height row when it is free add nothing to H or c) and weighs every row in one
product: each task writes its unweighted rows (:meth:`~mbctl.control.tasks.base.Task.write_velocity_rows`),
then ``W = diag(cost) J`` and ``r = -diag(gain cost) e`` for the whole stack at once. The weights
are cached and re-read when any task's cost, gain or LM damping changes.

At the acceleration level the stack weighs and damps in the same way: a stacked task
(``stacked_acceleration``: the CoM, frame orientations) writes its Jacobian and its terms
``a_des + kd J v - Jdot v`` unweighted (:meth:`~mbctl.control.tasks.base.Task.write_acceleration_terms`;
a Jacobian that is the same at every state, a frame on a free-flyer root's, is written once), then
``W = diag(cost) J`` and ``-r = -diag(cost) terms + diag(kd cost) J v`` are one product each for
the whole stack; other tasks write their weighted rows whole (weight 1, no damping in the stack).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from scipy.linalg.blas import dgemm, dgemv

from mbctl.control.tasks.base import Task, dot_into, weights_epoch
from mbctl.control.tasks.diagonal import DiagonalTask
from mbctl.control.tasks.state import DynamicsState, TaskState

#: A task's method that writes its rows at a state: (state, J_t or W_t, r_t) -> None
_RowWriter = Callable[[DynamicsState, np.ndarray, np.ndarray], None]


def _gram_into(W: np.ndarray, H: np.ndarray) -> None:
    """``H[:] = W^T W`` (nv, nv) for the rows ``W`` (m, nv), C-contiguous.

    By BLAS's gemm, ``W^T (W^T)^T`` (W^T is Fortran-contiguous: no copy), written in place into H
    when it is Fortran-contiguous, or into ``H.T`` when H is C-contiguous: ~1.1 us against 1.8 for a
    copy of W^T and np.dot's gemm at the WBC's sizes (np.matmul(W.T, W) calls syrk and mirrors,
    slower still).
    """
    if H.flags.f_contiguous or H.flags.c_contiguous:  # (symmetric: H or H^T, whichever is Fortran's)
        # positional: beta, c, trans_a, trans_b, overwrite_c
        dgemm(1.0, W.T, W.T, 0.0, H if H.flags.f_contiguous else H.T, 0, 1, 1)
    else:
        H[:] = W.T @ W


class TaskStack:
    """A fixed set of tasks and their preallocated least-squares rows.

    Attributes:
        tasks: The tasks, in order.
        nv: Tangent dimension (columns of every row).
    """

    def __init__(self, nv: int, tasks: Sequence[Task] = ()):
        self.nv = nv
        self._tmp = np.zeros(nv)
        self._diag_view: tuple[np.ndarray, np.ndarray] | None = None
        self.set_tasks(tasks)

    def set_tasks(self, tasks: Sequence[Task]) -> None:
        """Replace the task set (buffers are reallocated; targets may change freely between cycles)."""
        self.tasks = tuple(tasks)
        self._diagonal = tuple(t for t in self.tasks if isinstance(t, DiagonalTask) and t.is_diagonal)
        dense = tuple(t for t in self.tasks if t not in self._diagonal)
        n_rows = sum(t.k for t in dense)
        self._W = np.zeros((n_rows, self.nv))  # the acceleration-level rows (see _acceleration_layout)
        self._r = np.zeros(n_rows)
        self._velocity_epoch = -1  # the velocity-level layout is built on first use
        self._acc_key: tuple | None = None  # and the acceleration-level one

    def _velocity_layout(self) -> None:
        """(Re)build the velocity-level rows: active rows only, with their weights stacked."""
        dense = [t for t in self.tasks if t not in self._diagonal]
        rows = [t.active_rows() for t in dense]
        n_rows = sum(len(a) for a in rows)
        self._Wv = np.zeros((n_rows, self.nv))
        self._WvT = np.zeros((self.nv, n_rows))
        self._rv = np.zeros(n_rows)
        views, row = [], 0
        col, r_scale, lm = [], [], []
        for t, a in zip(dense, rows, strict=True):
            if len(a):
                views.append((t, self._Wv[row:row + len(a)], self._rv[row:row + len(a)]))
                row += len(a)
                col.append(t.cost[a])
                r_scale.append(t.gain * t.cost[a])  # the rows hold -r (c = W^T (-r) with no negation)
                lm.append(np.full(len(a), t.lm_damping))
        self._vviews = tuple(views)
        # each row's weight repeated along the row: one contiguous product (a (m, 1) column would
        # broadcast as m inner loops, ~0.6 us slower)
        self._col = np.repeat(np.concatenate(col)[:, None] if col else np.zeros((0, 1)), self.nv, axis=1)
        self._r_scale = np.concatenate(r_scale) if r_scale else np.zeros(0)
        lm_rows = np.concatenate(lm) if lm else np.zeros(0)
        self._lm_rows = lm_rows if np.any(lm_rows > 0.0) else None
        self._diag_terms = tuple((t, t.cost2_mask(), t.gain * t.cost2_mask(), t.gain * t.cost * t.mask)
                                 for t in self._diagonal)
        self._velocity_epoch = weights_epoch()

    def velocity_rows(self) -> tuple[np.ndarray, np.ndarray]:
        """The weighted rows ``(W (m, nv), r (m,))`` written by the last :meth:`velocity_objective`.

        Active rows of the dense tasks only (diagonal tasks go straight onto H); ``W`` is a view
        into the stack's buffer (overwritten by the next call), ``r`` a copy.
        """
        return self._Wv, -self._rv

    def _diagonal_of(self, H: np.ndarray) -> np.ndarray:
        """A writable view of ``H``'s diagonal, made once per buffer (einsum costs ~2 us a call)."""
        cached = self._diag_view
        if cached is None or cached[0] is not H:
            cached = self._diag_view = (H, np.einsum("ii->i", H))
        return cached[1]

    def velocity_objective(self, state: TaskState, H: np.ndarray, c: np.ndarray) -> float:
        """Write the IK objective over ``dq`` into ``H`` (nv, nv) and ``c`` (nv,); return the LM term.

        Returns:
            ``sum_t lm_damping_t |r_t|^2`` [cost^2], for the caller to add to H's diagonal.
        """
        if self._velocity_epoch != weights_epoch():
            self._velocity_layout()
        for task, J_t, e_t in self._vviews:
            task.write_velocity_rows(state, J_t, e_t)
        W, r_neg = self._Wv, self._rv
        W *= self._col
        r_neg *= self._r_scale
        mu = 0.0 if self._lm_rows is None else float((r_neg * r_neg) @ self._lm_rows)
        if W.shape[0]:
            # W^T copied to its own buffer: np.dot on (W.T, W) would see one buffer and call BLAS
            # syrk, ~2 us slower at these sizes than the copy and a gemm; np.dot: ~1.5 us less than
            # np.matmul on the same gemm
            WT = self._WvT
            np.copyto(WT, W.T)
            dot_into(WT, W, H)
            np.dot(r_neg, W, out=c)
        else:
            H.fill(0.0)
            c.fill(0.0)
        if self._diag_terms:
            diag = self._diagonal_of(H)
            tmp = self._tmp
            for task, cost2_mask, gain_cost2_mask, gain_cost in self._diag_terms:
                # W_t = diag(cost mask), r_t = -gain cost e  =>  H += cost^2 mask, c += gain cost^2 mask e
                diag += cost2_mask
                if task.gain > 0.0:  # with gain 0, r_t and so the LM term are zero too
                    e = task.masked_error(state)
                    np.multiply(gain_cost2_mask, e, out=tmp)
                    c += tmp
                    if task.lm_damping > 0.0:
                        err = gain_cost * e
                        mu += task.lm_damping * float(err @ err)
        return mu

    def _acceleration_layout(self, state: DynamicsState, regularization: float) -> None:
        """(Re)build the acceleration-level rows: the weights and damping of the stacked tasks' rows.

        Stacked tasks (``stacked_acceleration``) write ``J`` and their terms unweighted; the others
        write their weighted rows whole, so their rows' weight is 1 and their damping 0.
        """
        dense = [t for t in self.tasks if t not in self._diagonal]
        n_rows, nv = self._W.shape
        self._J = np.zeros((n_rows, nv))
        self._Jv = np.zeros(n_rows)
        self._rn = np.zeros(n_rows)
        writers: list[tuple[_RowWriter, np.ndarray, np.ndarray]] = []
        col, kd_cost, row = [], [], 0
        for t in dense:
            J_t, r_t = self._J[row:row + t.k], self._r[row:row + t.k]
            row += t.k
            if t.stacked_acceleration:
                constant = t.constant_acceleration_jacobian(state)
                if constant is not None:
                    J_t[:] = constant  # written once: the task leaves these rows alone
                writers.append((t.write_acceleration_terms, J_t, r_t))
                col.append(t.cost)
                kd_cost.append(t.servo.kd * t.cost)
            else:
                writers.append((t.write_acceleration_rows, J_t, r_t))
                col.append(np.ones(t.k))
                kd_cost.append(np.zeros(t.k))
        self._acc_writers = tuple(writers)
        weights = np.concatenate(col) if col else np.zeros(0)
        self._acc_col = np.repeat(weights[:, None], nv, axis=1)  # contiguous (see _velocity_layout)
        self._acc_neg_weight = -weights
        self._acc_kd_cost = np.concatenate(kd_cost) if kd_cost else np.zeros(0)
        self._acc_damped = bool(np.any(self._acc_kd_cost))
        # every row stacked with one kd (e.g. tasks with the same gains): diag(kd cost) J v = kd W v
        kd = {t.servo.kd for t in dense if t.stacked_acceleration}
        uniform = len(kd) == 1 and all(t.stacked_acceleration for t in dense)
        self._acc_kd_uniform = kd.pop() if uniform else None
        diag = np.full(nv, float(regularization))
        for task in self._diagonal:
            diag += task.cost2_mask()
        self._acc_diag = diag
        self._acc_key = (weights_epoch(), state.model, regularization)

    def acceleration_objective(self, state: DynamicsState, H: np.ndarray, c: np.ndarray,
                               regularization: float = 0.0) -> None:
        """Write the inverse-dynamics objective over ``vdot`` into ``H`` (nv, nv) and ``c`` (nv,).

        Args:
            state: Dynamics state.
            H: (nv, nv) output, ``W^T W`` plus the diagonal tasks' terms and ``regularization``.
            c: (nv,) output, ``-W^T r`` plus the diagonal tasks' terms.
            regularization: Added to H's diagonal [cost^2] (e.g. ``w_r^2`` of ``w_r^2 |vdot|^2``).
        """
        if self._acc_key != (weights_epoch(), state.model, regularization):
            self._acceleration_layout(state, regularization)
        for write, J_t, r_t in self._acc_writers:
            write(state, J_t, r_t)
        W, r_neg = self._W, self._rn
        if W.shape[0]:
            # W = diag(cost) J and -r = -diag(cost) (terms - kd J v) for every row at once (the
            # rows written whole have weight 1 and no damping)
            J = self._J
            np.multiply(J, self._acc_col, out=W)
            np.multiply(self._r, self._acc_neg_weight, out=r_neg)
            if self._acc_kd_uniform is not None:
                # r_neg += kd W v in place by one BLAS call, y = alpha A x + beta y (positional: beta,
                # y, offx, incx, offy, incy, trans, overwrite_y): ~1 us less than the three below
                dgemv(self._acc_kd_uniform, W.T, state.v, 1.0, r_neg, 0, 1, 0, 1, 1, 1)
            elif self._acc_damped:
                Jv = self._Jv
                np.dot(J, state.v, out=Jv)
                Jv *= self._acc_kd_cost
                r_neg += Jv
            _gram_into(W, H)
            np.dot(r_neg, W, out=c)  # c = -W^T r (~0.4 us less than np.matmul, the same product)
        else:
            H.fill(0.0)
            c.fill(0.0)
        diag = self._diagonal_of(H)
        diag += self._acc_diag
        for task in self._diagonal:
            # W_t = diag(cost mask), r_t = cost mask (a_des - 0)  =>  H += cost^2 mask, c -= cost^2 mask a_des
            task.add_acceleration_term(state, c, self._tmp)
