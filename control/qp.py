"""The QP floor under differential IK and whole-body inverse dynamics: daqp called directly.

Every QP of ``control/ik`` and ``control/wbc`` is, over ``x`` (n,)::

    min_x  1/2 x^T H x + c^T x
    s.t.   lb <= x <= ub,   h_lo <= G x <= h,   A x = b

held in a :class:`QPData` and solved by a :class:`QPSolver`, which returns a :class:`QPResult`.

* **daqp, called directly** (``daqp.solve``): the box goes in as daqp's simple bounds, ``G`` and
  ``A`` as its general rows, in that order (equalities with sense 5). The bound and sense arrays
  (and the stacked rows when both ``G`` and ``A`` are given) are buffers reused between calls,
  grown to the most rows seen. On the humanoid IK QP (35 variables) this took 6.8 us against
  13.4 us through ``qpsolvers.solve_problem``, same solution to the last bit (measured when the IK
  adapter was written; ``bench/bench_ik.py`` reports daqp's share of an iteration).
* **Every other backend** (``osqp``, ``proxqp``...) goes through ``qpsolvers`` on the same data,
  for comparison (:func:`solve_qpsolvers`).

Infinity. A bound at or beyond ``+-QP_INFINITY`` (1e30, daqp's and OSQP's infinity), ``+-inf``
included, is absent. The data go to daqp as they are: daqp 0.11 gives bit-identical solutions
and exit flags with ``+-inf`` and with ``+-1e30`` (checked on 3000 random QPs with bounds, two-sided
rows and equalities), so no clipping pass is needed (``np.clip`` costs ~4.6 us per vector).

Results. ``x`` is finite or None. daqp's objective value is finite exactly when its ``x`` is
(``x^T H x`` with H positive definite carries any NaN or inf of x; checked on 4000 random QPs with
a NaN or inf in H, c, A or a bound), so the check costs one ``math.isfinite``. Contradictory bounds
(a lower above its upper, on x or on a row) give :data:`CONTRADICTORY`: checked before a
qpsolvers backend is called (OSQP refuses such data outright), and after daqp fails (daqp reports
them as infeasible, exit flag -1).

Failures. :func:`infeasible_error` builds the caller's error class
(:class:`~mbctl.control.exceptions.IKInfeasible`, :class:`~mbctl.control.exceptions.WBCInfeasible`)
with the QP as a ``qpsolvers.Problem``, a ``qpsolvers.Solution`` with ``found = False``, and a
message that names the solver's status and any contradictory bounds.
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Callable
from typing import Any, NamedTuple, TypeVar

import daqp
import numpy as np
import qpsolvers
from qpsolvers.warnings import SparseConversionWarning

from mbctl.control.exceptions import ControlError

#: Magnitude standing for "no bound" (daqp's and OSQP's infinity); +-inf means the same.
QP_INFINITY = 1e30

#: Status of a solved QP (daqp's exit flag; 2 is daqp's "soft optimal").
OPTIMAL = 1

#: daqp's exit flag of an infeasible QP.
INFEASIBLE = -1

#: Status of bounds that contradict each other (a lower above its upper), found before or after a solve.
CONTRADICTORY = -100

#: Status of a backend that found no solution, or a non-finite one (from non-finite data).
NOT_FOUND = -101

#: What each status means (daqp's exit flags, then ours).
STATUS_TEXT = {
    2: "soft optimal",
    1: "optimal",
    -1: "infeasible",
    -2: "cycling",
    -3: "unbounded",
    -4: "iteration limit reached",
    -5: "non-convex problem",
    -6: "overdetermined initial active set",
    -7: "time limit reached",
    CONTRADICTORY: "contradictory bounds",
    NOT_FOUND: "no finite solution found",
}

#: daqp's sense flag of an equality row (active and immutable).
DAQP_EQUALITY = 5

#: Contradictory bounds listed in a message, at most.
_LISTED = 8

_E = TypeVar("_E", bound=ControlError)


class QPData(NamedTuple):
    """One QP's data (views into the caller's buffers; :meth:`problem` copies).

    Attributes:
        H: Hessian (n, n), symmetric positive definite.
        c: Linear term (n,).
        lb: Lower bounds on x (n,), or None (none).
        ub: Upper bounds on x (n,), or None (none).
        G: Inequality rows (m, n), or None.
        h: Their upper bounds (m,).
        A: Equality rows (p, n), or None.
        b: Their right-hand side (p,).
        h_lo: Lower bounds of the inequality rows (m,), or None (one-sided rows ``G x <= h``).
    """

    H: np.ndarray
    c: np.ndarray
    lb: np.ndarray | None = None
    ub: np.ndarray | None = None
    G: np.ndarray | None = None
    h: np.ndarray | None = None
    A: np.ndarray | None = None
    b: np.ndarray | None = None
    h_lo: np.ndarray | None = None

    def problem(self, copy: bool = True) -> qpsolvers.Problem:
        """The QP as a ``qpsolvers.Problem`` (one-sided rows: ``G x <= h``).

        Two-sided rows become ``G x <= h`` on their finite upper bounds, then ``-G x <= -h_lo`` on
        their finite lower bounds.

        Args:
            copy: Copy every array (for errors and inspection); False passes views where it can.
        """

        def cp(x: np.ndarray | None) -> np.ndarray | None:
            return np.array(x, copy=True) if copy and x is not None else x

        G, h = self.G, self.h
        if G is not None and self.h_lo is not None and h is not None:
            up, lo = h < QP_INFINITY, self.h_lo > -QP_INFINITY
            G = np.vstack([G[up], -G[lo]])
            h = np.concatenate([h[up], -self.h_lo[lo]])
        else:
            G, h = cp(G), cp(h)
        H, c = (self.H.copy(), self.c.copy()) if copy else (self.H, self.c)
        return qpsolvers.Problem(H, c, G, h, cp(self.A), cp(self.b), cp(self.lb), cp(self.ub))


class QPResult(NamedTuple):
    """One solve.

    Attributes:
        x: The solution (n,), finite, or None when the QP has none.
        status: daqp's exit flag (:data:`OPTIMAL` 1; < 0 failed, see :data:`STATUS_TEXT`), or
            :data:`CONTRADICTORY` / :data:`NOT_FOUND`; 1 for a closed-form or qpsolvers solution.
        iterations: Active-set iterations (daqp's count; 0 for a closed form, -1 when the backend
            does not report them).
        solve_time_s: Time spent in the backend [s].
        fast_path: Whether a closed form gave x without a solver (the WBC's equality-constrained path).
        dependent_rows: Equality rows dropped as linearly dependent on the others.
        duals: daqp's Lagrange multipliers (box, inequality rows, equality rows; > 0 where an
            upper bound is active, < 0 at a lower one), or None.
    """

    x: np.ndarray | None
    status: int
    iterations: int
    solve_time_s: float
    fast_path: bool = False
    dependent_rows: int = 0
    duals: np.ndarray | None = None


class QPSolver:
    """Solves QPs of ``n`` variables with one backend, reusing daqp's buffers between calls.

    Args:
        n: Number of variables.
        solver: Backend name: ``daqp`` is called directly, any other through qpsolvers (the
            caller checks that it is installed).
        options: Keyword arguments for the backend (e.g. daqp's ``primal_tol``).

    Attributes:
        solver: Backend name.
        options: Keyword arguments for the backend.
    """

    def __init__(self, n: int, solver: str = "daqp", options: dict[str, Any] | None = None):
        self.solver = solver
        self.options = dict(options or {})
        self._n = n
        self._no_rows = np.zeros((0, n))
        self._no_bounds = np.zeros(0)
        self._rows = np.zeros((0, n))  # G and A stacked, when both are given
        self._upper, self._lower = np.empty(n), np.empty(n)  # simple bounds, then the rows'
        self._sense = np.zeros(n, dtype=np.intc)
        self._layout = (n, 0, 0)  # (box, inequality, equality) rows the sense buffer is set for
        self._box_sense = np.zeros(n, dtype=np.intc)  # the senses of a box alone

    def solve(self, qp: QPData) -> QPResult:
        """Solve ``qp`` (its ``x`` has this solver's ``n`` entries); ``x`` is None when it has no solution."""
        if self.solver == "daqp":
            return self._daqp(qp)
        return solve_qpsolvers(qp, self.solver, self.options)

    def _daqp(self, qp: QPData) -> QPResult:
        if qp.G is None and qp.A is None and qp.lb is not None and qp.ub is not None:
            A, upper, lower, sense = self._no_rows, qp.ub, qp.lb, self._box_sense  # a box only: no copy
        else:
            A, upper, lower, sense = self._pack(qp)
        result = solve_packed(qp.H, qp.c, A, upper, lower, sense, self.options)
        if result.x is not None:
            return result
        # no solution, or a non-finite one (from non-finite data): say why
        flag = result.status
        status = CONTRADICTORY if _contradictions(qp) else (NOT_FOUND if flag > 0 else flag)
        return result._replace(status=status)

    def _pack(self, qp: QPData) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The rows, upper and lower bounds and senses for daqp: the box, then ``G``, then ``A``."""
        G, A = qp.G, qp.A
        m_in = 0 if G is None else G.shape[0]
        m_eq = 0 if A is None else A.shape[0]
        n_box = 0 if qp.lb is None and qp.ub is None else self._n
        if not (m_in or m_eq):
            if not n_box:
                return self._no_rows, self._no_bounds, self._no_bounds, self._sense[:0]
            if qp.lb is not None and qp.ub is not None:  # the caller's arrays, no copy
                return self._no_rows, qp.ub, qp.lb, self._senses(n_box, 0, 0)
        if G is not None and m_in and A is not None and m_eq:
            if self._rows.shape[0] < m_in + m_eq:
                self._rows = np.zeros((2 * (m_in + m_eq), self._n))
            rows = self._rows[:m_in + m_eq]
            rows[:m_in] = G
            rows[m_in:] = A
        elif G is not None and m_in:
            rows = G
        else:
            rows = self._no_rows if A is None else A
        m = n_box + m_in + m_eq
        if len(self._upper) < m:  # grown to the most rows seen, then reused
            self._upper, self._lower = np.empty(2 * m), np.empty(2 * m)
        upper, lower = self._upper[:m], self._lower[:m]
        if n_box:
            upper[:n_box] = QP_INFINITY if qp.ub is None else qp.ub
            lower[:n_box] = -QP_INFINITY if qp.lb is None else qp.lb
        if m_in:
            upper[n_box:n_box + m_in] = qp.h
            lower[n_box:n_box + m_in] = -QP_INFINITY if qp.h_lo is None else qp.h_lo
        if m_eq:
            upper[n_box + m_in:] = qp.b
            lower[n_box + m_in:] = qp.b
        return rows, upper, lower, self._senses(n_box, m_in, m_eq)

    def _senses(self, n_box: int, m_in: int, m_eq: int) -> np.ndarray:
        """The sense buffer for this layout (rewritten only when the layout changes: daqp reads it only)."""
        m = n_box + m_in + m_eq
        if len(self._sense) < m:
            self._sense = np.zeros(2 * m, dtype=np.intc)
            self._layout = (-1, -1, -1)
        if self._layout != (n_box, m_in, m_eq):
            self._sense[:n_box + m_in] = 0
            self._sense[n_box + m_in:m] = DAQP_EQUALITY
            self._layout = (n_box, m_in, m_eq)
        return self._sense[:m]


def solve_packed(H: np.ndarray, c: np.ndarray, A: np.ndarray, upper: np.ndarray, lower: np.ndarray,
                 sense: np.ndarray, options: dict[str, Any] | None = None) -> QPResult:
    """Solve with daqp on its packing: the first ``len(upper) - len(A)`` entries bound x, the rest ``A x``.

    Returns:
        The result, ``x`` None (and ``status`` daqp's flag) when daqp finds no finite solution.
    """
    t0 = time.perf_counter()
    x, fval, flag, info = daqp.solve(H, c, A, upper, lower, sense, **(options or {}))
    elapsed = time.perf_counter() - t0
    if flag > 0 and math.isfinite(fval):
        return QPResult(x, flag, info["iterations"], elapsed, duals=info["lam"])
    return QPResult(None, flag, info["iterations"], elapsed)


def solve_qpsolvers(qp: QPData, solver: str, options: dict[str, Any] | None = None) -> QPResult:
    """Solve ``qp`` with a qpsolvers backend (for comparison with daqp; not a hot path).

    Args:
        qp: The QP.
        solver: A name in ``qpsolvers.available_solvers`` (the caller checks it).
        options: Keyword arguments for the backend.

    Returns:
        The result: ``x`` finite or None, status :data:`OPTIMAL`, :data:`NOT_FOUND` or
        :data:`CONTRADICTORY` (checked before the call), ``iterations`` -1 (not reported).
    """
    if _contradictions(qp):
        return QPResult(None, CONTRADICTORY, 0, 0.0)
    problem = qp.problem(copy=False)
    with warnings.catch_warnings():
        # OSQP wants a sparse P; qpsolvers converts our dense one and says so each call.
        warnings.simplefilter("ignore", SparseConversionWarning)
        # osqp 1.x announces a future default; a failed solve is reported by the caller.
        warnings.filterwarnings("ignore", message="The default value of raise_error")
        warnings.filterwarnings("ignore", message="OSQP exited with status")
        result = qpsolvers.solve_problem(problem, solver=solver, **(options or {}))
    x = result.x if result.found and result.x is not None else None
    if x is not None and not np.isfinite(x).all():
        x = None
    return QPResult(x, OPTIMAL if x is not None else NOT_FOUND, -1, float(result.solve_time or 0.0))


def contradictory_bounds(lower: np.ndarray | None, upper: np.ndarray | None) -> np.ndarray:
    """Indices where ``lower`` exceeds ``upper`` (an empty array if either is None)."""
    if lower is None or upper is None:
        return np.zeros(0, dtype=int)
    return np.flatnonzero(np.asarray(lower) > np.asarray(upper))


def _contradictions(qp: QPData) -> bool:
    return bool(len(contradictory_bounds(qp.lb, qp.ub)) or len(contradictory_bounds(qp.h_lo, qp.h)))


def describe_contradictions(qp: QPData) -> str:
    """Which bounds of ``qp`` contradict each other, with their values ("" if none).

    Example: ``"lower above upper at x[0, 3]: [1.0, 0.5] > [-1.0, 0.2]"``.
    """
    parts = []
    for what, lower, upper in (("x", qp.lb, qp.ub), ("row", qp.h_lo, qp.h)):
        bad = contradictory_bounds(lower, upper)[:_LISTED]
        if len(bad) and lower is not None and upper is not None:
            parts.append(f"lower above upper at {what}[{', '.join(map(str, bad.tolist()))}]: "
                         f"{np.round(lower[bad], 6).tolist()} > {np.round(upper[bad], 6).tolist()}")
    return "; ".join(parts)


def status_text(status: int) -> str:
    """``status`` as words, e.g. ``"exit flag -1 (infeasible)"``."""
    return f"exit flag {status} ({STATUS_TEXT.get(status, 'unknown')})"


def infeasible_error(error: Callable[..., _E], what: str, advice: str, qp: QPData, result: QPResult,
                     solver: str, **context: Any) -> _E:
    """The caller's error for a QP without solution, carrying the QP and a failed ``qpsolvers.Solution``.

    The message is ``"{what} ({solver}: {status}[; contradictory bounds]). {advice}"``.

    Args:
        error: The error class, called as ``error(message, problem, solution, solver, **context)``
            (e.g. :class:`~mbctl.control.exceptions.IKInfeasible`).
        what: What failed, for the message (e.g. "QP solver 'daqp' found no IK step").
        advice: What to do next, for the message.
        qp: The QP (copied into the error).
        result: The failed solve.
        solver: Backend name.
        **context: Further keyword arguments of ``error`` (e.g. ``time_s``).

    Returns:
        The error, to raise.
    """
    detail = describe_contradictions(qp) if result.status == CONTRADICTORY else ""
    message = f"{what} ({solver}: {status_text(result.status)}{'; ' + detail if detail else ''}). {advice}"
    problem = qp.problem()
    solution = qpsolvers.Solution(problem)
    solution.found = False
    solution.extras = {"status": result.status, "iterations": result.iterations}
    return error(message, problem, solution, solver, **context)
