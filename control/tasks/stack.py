"""The tasks' weighted least squares as a QP objective, assembled once for IK and for inverse dynamics.

Every task writes rows ``W_t x ≈ r_t`` (velocity level: ``x = dq``; acceleration level:
``x = vdot``; see :mod:`mbctl.control.tasks.base`). Stacked, they give::

    1/2 |W x - r|^2  =  1/2 x^T H x + c^T x + const,   H = W^T W,   c = -W^T r

Diagonal tasks (posture, damping; :mod:`mbctl.control.tasks.diagonal`) go straight onto H's
diagonal (``cost^2 mask``) and into c instead of adding nv rows each. The row buffers are allocated
once per task set and reused every cycle; the two QPs (differential IK, whole-body inverse
dynamics) call this one assembly.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from mbctl.control.tasks.base import Task
from mbctl.control.tasks.diagonal import DiagonalTask
from mbctl.control.tasks.state import DynamicsState, TaskState


class TaskStack:
    """A fixed set of tasks and their preallocated least-squares rows.

    Attributes:
        tasks: The tasks, in order.
        nv: Tangent dimension (columns of every row).
    """

    def __init__(self, nv: int, tasks: Sequence[Task] = ()):
        self.nv = nv
        self._tmp = np.zeros(nv)
        self.set_tasks(tasks)

    def set_tasks(self, tasks: Sequence[Task]) -> None:
        """Replace the task set (buffers are reallocated; targets may change freely between cycles)."""
        self.tasks = tuple(tasks)
        self._diagonal = tuple(t for t in self.tasks if isinstance(t, DiagonalTask) and t.is_diagonal)
        dense = tuple(t for t in self.tasks if t not in self._diagonal)
        n_rows = sum(t.k for t in dense)
        self._W = np.zeros((n_rows, self.nv))
        self._r = np.zeros(n_rows)
        views, row = [], 0
        for t in dense:
            views.append((t, self._W[row:row + t.k], self._r[row:row + t.k]))
            row += t.k
        self._views = tuple(views)

    def _hessian(self, H: np.ndarray, c: np.ndarray) -> np.ndarray:
        """``H = W^T W``, ``c = -W^T r`` from the filled rows; returns H's diagonal (a writable view)."""
        W = self._W
        if W.shape[0]:
            np.matmul(W.T, W, out=H)
            np.matmul(self._r, W, out=c)
            np.negative(c, out=c)
        else:
            H.fill(0.0)
            c.fill(0.0)
        return np.einsum("ii->i", H)

    def velocity_objective(self, state: TaskState, H: np.ndarray, c: np.ndarray) -> float:
        """Write the IK objective over ``dq`` into ``H`` (nv, nv) and ``c`` (nv,); return the LM term.

        Returns:
            ``sum_t lm_damping_t |r_t|^2`` [cost^2], for the caller to add to H's diagonal.
        """
        mu = 0.0
        for task, W_t, r_t in self._views:
            mu += task.write_qp_rows(state, W_t, r_t)
        diag = self._hessian(H, c)
        tmp = self._tmp
        for task in self._diagonal:
            # W_t = diag(cost mask), r_t = -gain cost e  =>  H += cost^2 mask, c += gain cost^2 mask e
            cost2_mask = task.cost2_mask()
            diag += cost2_mask
            if task.gain > 0.0:  # with gain 0, r_t and so the LM term are zero too
                e = task.compute_error(state)
                np.multiply(cost2_mask, e, out=tmp)
                tmp *= task.gain
                c += tmp
                if task.lm_damping > 0.0:
                    err = task.gain * task.cost * e
                    mu += task.lm_damping * float(err @ err)
        return mu

    def acceleration_objective(self, state: DynamicsState, H: np.ndarray, c: np.ndarray) -> None:
        """Write the inverse-dynamics objective over ``vdot`` into ``H`` (nv, nv) and ``c`` (nv,)."""
        for task, W_t, r_t in self._views:
            task.write_acceleration_rows(state, W_t, r_t)
        diag = self._hessian(H, c)
        tmp = self._tmp
        for task in self._diagonal:
            # W_t = diag(cost mask), r_t = cost mask (a_des - 0)  =>  H += cost^2 mask, c -= cost^2 mask a_des
            cost2_mask = task.cost2_mask()
            diag += cost2_mask
            a_des = task.desired_acceleration(state, task.jacobian_and_drift(state)[0])
            np.multiply(cost2_mask, a_des, out=tmp)
            c -= tmp
