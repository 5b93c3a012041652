"""daqp on the whole-body QP without its pinned forces and its deferred rows, when that is its optimum.

Pinned forces (:attr:`~mbctl.control.wbc.qp.WholeBodyQP.force_free` False: a released foot's, its
bounds [0, 0]) are zero in every feasible point, so leaving them out (with the rows that only
involve them) changes nothing; leaving out the deferred rows (rows rarely active: the controller's
torque limits) relaxes the QP, so its optimum is the whole QP's when it satisfies every bound and
row of the whole QP, which :meth:`ReducedQP.solve` checks.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from mbctl.control.qp import DAQP_EQUALITY, QPResult, solve_packed

if TYPE_CHECKING:
    from mbctl.control.wbc.qp import WholeBodyQP

#: Largest violation [problem units] of a deferred row that the reduced QP's optimum may have and
#: still count as the whole QP's (daqp's own primal tolerance).
DEFERRED_TOL = 1e-6


class _Reduction:
    """The reduced QP's kept variables and rows, and its daqp packing (:meth:`ReducedQP.solve`).

    ``upper`` and ``lower`` bound the kept variables, then the kept rows, then the equalities;
    ``A`` holds the kept rows, then the equalities, over the kept variables.
    """

    def __init__(self, keep: np.ndarray, rows: np.ndarray, pinned_rows: np.ndarray, n_x: int, m_eq_max: int,
                 force_weight: float):
        self.keep, self.rows = keep, rows
        #: (n_x + m_in,) the bounds and rows that involve pinned forces only
        self.pinned_rows = pinned_rows
        k, r = len(keep), len(rows)
        self.bounds_at = np.concatenate([keep, n_x + rows])  # in [x; G x]
        self.H = np.zeros((k, k))
        self.force_weight = force_weight
        self.c = np.zeros(k)
        self.A = np.zeros((r + m_eq_max, k))
        self.upper = np.zeros(k + r + m_eq_max)
        self.lower = np.zeros(k + r + m_eq_max)
        self.sense = np.zeros(k + r + m_eq_max, dtype=np.intc)
        self.sense[k + r:] = DAQP_EQUALITY


class ReducedQP:
    """The reduced QPs of a :class:`~mbctl.control.wbc.qp.WholeBodyQP` (one per pin pattern), on its buffers.

    Args:
        qp: The QP whose buffers it reads (and whose feasibility check it uses).
    """

    def __init__(self, qp: WholeBodyQP):
        self._qp = qp
        self._reductions: dict[tuple, _Reduction] = {}

    def pinned_rows(self) -> np.ndarray:
        """(n_x + m_in,) whether a bound or row involves pinned forces only (at G's present pattern)."""
        qp = self._qp
        pinned_f = qp._free_f == 0.0
        out = np.zeros(qp.n_x + qp.m_in, dtype=bool)
        out[qp.nv:qp.n_x] = pinned_f
        G_v_zero = ~qp.G[:, :qp.nv].any(axis=1)
        touches_free = (qp.G[:, qp.nv:] != 0.0) @ ~pinned_f
        out[qp.n_x:] = G_v_zero & ~touches_free
        return out

    def reduction(self, defer: bool = True) -> _Reduction:
        """The variables and rows of the reduced QP for the present pins (made once per pattern).

        Args:
            defer: Leave out the deferred rows too (else only what involves pinned forces alone).

        Made with G's pattern of non-zeros at the time, taken as fixed while the pins stay. It
        decides which rows the reduced QP leaves out and whether the next solve tries the fast path
        first, never what the solution is: the reduced QP's point is checked against every row, so
        a stale pattern would cost a solve of the whole QP, not a wrong point.
        """
        qp = self._qp
        d = qp.deferred_rows if defer else None
        key = (qp._free_f.tobytes(), None if d is None else (d.start, d.stop, d.step))
        red = self._reductions.get(key)
        if red is None:
            keep = np.concatenate([np.arange(qp.nv), qp.nv + np.flatnonzero(qp._free_f)])
            pinned_rows = self.pinned_rows()
            left_out = pinned_rows[qp.n_x:].copy()
            if d is not None:
                left_out[d] = True
            red = _Reduction(keep, np.flatnonzero(~left_out), pinned_rows, qp.n_x, qp.m_eq_max, np.nan)
            self._reductions[key] = red
        if red.force_weight != qp._w_f:
            np.einsum("ii->i", red.H)[qp.nv:] = qp._w_f * qp._w_f
            red.force_weight = qp._w_f
        return red

    def solve(self, eq_rows: np.ndarray, consecutive: bool,
              defer: bool = True) -> tuple[QPResult, bool] | None:
        """Solve by daqp without the pinned forces (and the deferred rows), if that is the whole QP's optimum.

        Pinned forces are zero in every feasible point, so leaving them out (with the rows that
        only involve them) changes nothing; leaving out the deferred rows relaxes the QP, so its
        optimum is the whole QP's when it satisfies every bound and row of the whole QP (checked,
        to daqp's own primal tolerance, 1e-6). The reduced QP (e.g. the G1's in single support)
        has 47 variables and 28 rows against 59 and 73, and daqp's setup, redone every call,
        grows with n^2 m: ~60 us against ~125 us (measured on walking cycles).

        Without the deferred rows left out (``defer`` False) it is the whole QP's optimum whenever
        it has one: pinned forces are zero in every feasible point. daqp on the whole QP instead can
        report no solution where there is one: a released foot's normal forces pinned by equal bounds
        and its tangential ones by the friction rows at zero make a degenerate vertex (e.g. after a
        push while walking: the whole QP infeasible for daqp, exit -1, feasible for HiGHS' LP, and
        solved by daqp with the foot's forces left out).

        Args:
            eq_rows: The equality rows' indices.
            consecutive: They are the first ``len(eq_rows)`` rows.
            defer: Leave out the deferred rows too.

        Returns:
            ``(result, active)``: the result (its ``duals`` None: they are the reduced QP's) and
            whether an inequality or bound is active at it; None when a deferred row is violated
            or the reduced QP has no solution (the whole one then decides).
        """
        qp = self._qp
        red = self.reduction(defer)
        nv, k, r, m = qp.nv, len(red.keep), len(red.rows), len(eq_rows)
        red.H[:nv, :nv] = qp.H_vv
        red.c[:nv] = qp.c_v
        upper, lower, A = red.upper[:k + r + m], red.lower[:k + r + m], red.A[:r + m]
        np.take(qp._up, red.bounds_at, out=upper[:k + r])
        np.take(qp._lo, red.bounds_at, out=lower[:k + r])
        e = qp.e[:m] if consecutive else qp.e[eq_rows]
        upper[k + r:] = e
        lower[k + r:] = e
        np.take(qp.G[red.rows], red.keep, axis=1, out=A[:r])
        np.take(qp.E[:m] if consecutive else qp.E[eq_rows], red.keep, axis=1, out=A[r:])
        result = solve_packed(red.H, red.c, A, upper, lower, red.sense[:k + r + m])
        if result.x is None or result.duals is None:
            return None
        x = np.zeros(qp.n_x)
        x[red.keep] = result.x
        # every bound and row checked, the left-out ones included (the pinned forces' are met at zero)
        if not qp._feasible(x, DEFERRED_TOL):
            return None
        return result._replace(x=x, duals=None), bool(result.duals[:k + r].any())
