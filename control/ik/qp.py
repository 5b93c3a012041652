"""The QP of one differential-IK step (or one priority level of it), solved with preallocated data.

Each call solves, for the tangent step ``dq`` (nv,)::

    min_dq  1/2 dq^T H dq + c^T dq
    s.t.    lb <= dq <= ub,   G dq <= h,   A dq = b

With the ``daqp`` backend the solver is called directly (``daqp.solve``): the box is handed over as
daqp's simple bounds, ``G`` and ``A`` as its general rows (equalities with sense 5). Measured on the
humanoid whole-body IK QP (35 variables, 35 bounds): 6.8 us directly against 13.4 us through
``qpsolvers.solve_problem`` (its conversion and bookkeeping), same solution to the last bit; the
QPs are small, so the wrapper was half of the solve. Every other backend goes through qpsolvers.
"""

from __future__ import annotations

import time
import warnings
from ctypes import c_int
from typing import Any, NamedTuple

import daqp
import numpy as np
import qpsolvers
from qpsolvers.warnings import SparseConversionWarning

#: Magnitude standing for "no bound" in the QP (DAQP's and OSQP's infinity).
QP_INFINITY = 1e30

#: daqp's sense flag of an equality row.
_DAQP_EQUALITY = 5


class QPData(NamedTuple):
    """One QP's data (views into the caller's buffers; copy to keep).

    Attributes:
        H: Hessian (nv, nv).
        c: Linear term (nv,).
        lb: Lower bounds (nv,) or None.
        ub: Upper bounds (nv,) or None.
        G: Inequality rows (m, nv) or None.
        h: Their right-hand side (m,) or None.
        A: Equality rows (p, nv) or None.
        b: Their right-hand side (p,) or None.
    """

    H: np.ndarray
    c: np.ndarray
    lb: np.ndarray | None
    ub: np.ndarray | None
    G: np.ndarray | None
    h: np.ndarray | None
    A: np.ndarray | None
    b: np.ndarray | None

    def problem(self) -> qpsolvers.Problem:
        """A qpsolvers ``Problem`` holding copies of the data (for errors and inspection)."""

        def cp(x: np.ndarray | None) -> np.ndarray | None:
            return None if x is None else np.array(x, copy=True)

        return qpsolvers.Problem(self.H.copy(), self.c.copy(), cp(self.G), cp(self.h), cp(self.A), cp(self.b),
                                 cp(self.lb), cp(self.ub))


class QPOutcome(NamedTuple):
    """A solve's result.

    Attributes:
        x: The solution (nv,), or None when the backend found none.
        solve_time_s: Time spent in the backend [s].
        status: The backend's status (daqp's exit flag; qpsolvers' ``found``) for error messages.
    """

    x: np.ndarray | None
    solve_time_s: float
    status: Any


class StepQP:
    """Solves IK QPs of a fixed size ``nv`` with one backend.

    Attributes:
        solver: Backend name (``daqp`` is called directly; others through qpsolvers).
        options: Keyword arguments for the backend.
    """

    def __init__(self, nv: int, solver: str, options: dict[str, Any]):
        self.solver = solver
        self.options = options
        self._nv = nv
        self._no_rows = np.zeros((0, nv))
        self._box_sense = np.zeros(nv, dtype=c_int)
        self._no_bounds = np.zeros(0)
        self._upper, self._lower = np.empty(0), np.empty(0)  # daqp's bounds and row senses
        self._sense = np.zeros(0, dtype=c_int)

    def solve(self, qp: QPData) -> QPOutcome:
        """Solve ``qp``; ``x`` is None when the backend finds no solution."""
        if self.solver == "daqp":
            return self._daqp(qp)
        problem = qpsolvers.Problem(qp.H, qp.c, qp.G, qp.h, qp.A, qp.b, qp.lb, qp.ub)
        if self.solver == "osqp":
            if qp.lb is not None and qp.ub is not None and (qp.lb > qp.ub).any():
                # contradictory boxes (q outside its limits): OSQP refuses such data outright
                return QPOutcome(None, 0.0, "contradictory bounds")
            with warnings.catch_warnings():
                # OSQP wants a sparse P; qpsolvers converts our dense one and says so each call.
                warnings.simplefilter("ignore", SparseConversionWarning)
                # osqp 1.x announces a future default; a failed solve is reported by the caller.
                warnings.filterwarnings("ignore", message="The default value of raise_error")
                warnings.filterwarnings("ignore", message="OSQP exited with status")
                result = qpsolvers.solve_problem(problem, solver=self.solver, **self.options)
        else:
            result = qpsolvers.solve_problem(problem, solver=self.solver, **self.options)
        x = result.x if result.found and result.x is not None else None
        return QPOutcome(x, float(result.solve_time or 0.0), result.found)

    def _daqp(self, qp: QPData) -> QPOutcome:
        n_box = 0 if qp.ub is None else self._nv
        rows = ([] if qp.G is None and qp.A is None
                else [m for m in (qp.G, qp.A) if m is not None and m.shape[0]])
        if not rows:
            A = self._no_rows
            if n_box:
                upper, lower, sense = qp.ub, qp.lb, self._box_sense
            else:
                upper = lower = self._no_bounds
                sense = self._box_sense[:0]
        else:
            A = rows[0] if len(rows) == 1 else np.vstack(rows)
            m_in = 0 if qp.G is None else qp.G.shape[0]
            m_eq = 0 if qp.A is None else qp.A.shape[0]
            m = n_box + m_in + m_eq
            if len(self._upper) < m:  # buffers grow to the most rows seen, then are reused
                self._upper, self._lower = np.empty(2 * m), np.empty(2 * m)
                self._sense = np.zeros(2 * m, dtype=c_int)
            upper, lower, sense = self._upper[:m], self._lower[:m], self._sense[:m]
            lower.fill(-QP_INFINITY)
            sense.fill(0)
            if n_box:
                upper[:n_box] = qp.ub
                lower[:n_box] = qp.lb if qp.lb is not None else -QP_INFINITY
            if m_in:
                upper[n_box:n_box + m_in] = qp.h
            if m_eq:
                upper[n_box + m_in:] = qp.b
                lower[n_box + m_in:] = qp.b
                sense[n_box + m_in:] = _DAQP_EQUALITY
        t0 = time.perf_counter()
        x, _, flag, _ = daqp.solve(qp.H, qp.c, A, upper, lower, sense, **self.options)
        elapsed = time.perf_counter() - t0
        return QPOutcome(x if flag > 0 else None, elapsed, flag)
