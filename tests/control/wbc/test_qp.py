"""The whole-body QP's structured solve against qpsolvers on random problems of the same shape.

The equality-constrained fast path must give the QP's optimum whenever it claims to (no
inequality active), and hand over to daqp otherwise; both must match an independent solve.
"""

from __future__ import annotations

import numpy as np
import pytest
import qpsolvers
from hypothesis import given, settings
from hypothesis import strategies as st

from mbctl.control.qp import CONTRADICTORY, QPResult
from mbctl.control.wbc.qp import WholeBodyQP

NV, NF, M_IN, M_EQ = 9, 6, 10, 5


def _problem(seed: int, cut: float) -> WholeBodyQP:
    """A random QP of the controller's structure; ``cut`` > 0 moves three rows' upper bounds and a
    bound that far past the equality-constrained optimum (they become active), 0 leaves room."""
    rng = np.random.default_rng(seed)
    qp = WholeBodyQP(NV, NF, M_IN, M_EQ + 2, force_weight=0.3)
    W = rng.normal(size=(NV + 2, NV))
    qp.H_vv[:] = W.T @ W + 1e-3 * np.eye(NV)
    qp.c_v[:] = rng.normal(size=NV)
    qp.E[:M_EQ] = rng.normal(size=(M_EQ, NV + NF))
    qp.e[:M_EQ] = rng.normal(size=M_EQ)
    qp.G[:] = rng.normal(size=(M_IN, NV + NF))
    x_free = qp.solve(M_EQ).x  # fast path with no inequality yet
    g = qp.G @ x_free
    qp.g_lo[:] = g - 1.0
    qp.g_up[:] = g + 1.0
    qp.g_up[:3] = g[:3] - cut
    qp.lb[:NV] = x_free[:NV] - 1.0
    qp.ub[NV:] = x_free[NV:] + 1.0
    qp.ub[NV] = x_free[NV] - cut
    return qp


def _reference(qp: WholeBodyQP, m_eq: int) -> np.ndarray | None:
    """The optimum from qpsolvers' own daqp path on the exported problem (None: infeasible)."""
    solution = qpsolvers.solve_problem(qp.problem(m_eq), solver="daqp")
    return solution.x if solution.found else None


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10_000), st.sampled_from([0.0, 0.01, 0.2]))
def test_structured_solve_equals_qpsolvers(seed, cut):
    qp = _problem(seed, cut)
    result = qp.solve(M_EQ)
    reference = _reference(qp, M_EQ)
    # with room around the equality-constrained optimum the fast path takes it; when the
    # inequalities cut into it, daqp solves the whole QP: either way the optimum, or both find
    # none (a deep cut can make the random problem infeasible)
    assert result.fast_path == (cut == 0.0)
    if reference is None:
        assert result.x is None and result.status < 0
        return
    assert result.x is not None
    np.testing.assert_allclose(result.x, reference, atol=1e-6 * max(1.0, np.abs(reference).max()))
    E = qp.E[:M_EQ]
    np.testing.assert_allclose(E @ result.x, qp.e[:M_EQ], atol=1e-7)


def test_fast_path_point_satisfies_the_kkt_conditions():
    qp = _problem(3, 0.0)
    x = qp.solve(M_EQ).x
    H = qp.problem(M_EQ).P
    c = qp.problem(M_EQ).q
    E = qp.E[:M_EQ]
    # H x + c lies in the row space of E (stationarity with multipliers on the equalities only)
    grad = H @ x + c
    lam, *_ = np.linalg.lstsq(E.T, -grad, rcond=None)
    np.testing.assert_allclose(E.T @ lam, -grad, atol=1e-9)


def test_infeasible_problems_report_no_solution():
    qp = _problem(5, 0.0)
    qp.g_lo[0], qp.g_up[0] = 1.0, -1.0  # contradictory bounds of one row (daqp would pick a side)
    assert qp.solve(M_EQ) == QPResult(None, CONTRADICTORY, 0, 0.0, fast_path=False, dependent_rows=0)
    qp = _problem(5, 0.0)
    qp.G[1] = qp.G[0]  # the same row twice with disjoint ranges
    qp.g_lo[0], qp.g_up[0] = 0.0, 1.0
    qp.g_lo[1], qp.g_up[1] = 2.0, 3.0
    result = qp.solve(M_EQ)
    assert result.x is None and not result.fast_path and result.status < 0


def test_contradictory_bounds_are_reported_on_either_path():
    """Checked after the fast path's point fails them, and before daqp when the fast path is skipped."""
    qp = _problem(11, 0.2)
    assert not qp.solve(M_EQ).fast_path  # an inequality active: the next solve skips the fast path
    assert qp._skip_fast
    qp.lb[2], qp.ub[2] = 1.0, 0.5
    assert qp.solve(M_EQ) == QPResult(None, CONTRADICTORY, 0, 0.0, fast_path=False, dependent_rows=0)
    qp = _problem(11, 0.0)
    qp.lb[NV + 1], qp.ub[NV + 1] = 2.0, 1.0
    assert qp.solve(M_EQ).status == CONTRADICTORY


def test_forces_pinned_then_freed_give_a_fresh_problems_optimum():
    """force_free is read at every solve: pinned, then freed again, the solve equals a fresh QP's."""
    qp, fresh = _problem(21, 0.0), _problem(21, 0.0)
    before = qp.solve(M_EQ).x
    pinned = slice(NV + 3, NV + NF)
    lb, ub = qp.lb[pinned].copy(), qp.ub[pinned].copy()
    qp.lb[pinned] = qp.ub[pinned] = 0.0
    qp.force_free[pinned.start - NV:] = False
    assert np.abs(qp.solve(M_EQ).x[pinned]).max() == 0.0
    qp.lb[pinned], qp.ub[pinned] = lb, ub
    qp.force_free[:] = True
    np.testing.assert_allclose(qp.solve(M_EQ).x, before, atol=1e-12)  # daqp first (a bound was active)
    after = qp.solve(M_EQ)  # then the fast path again
    assert after.fast_path and np.abs(after.x[pinned]).max() > 1e-3
    np.testing.assert_array_equal(after.x, fresh.solve(M_EQ).x)
    np.testing.assert_array_equal(after.x, before)


@pytest.mark.filterwarnings("ignore:invalid value:RuntimeWarning")  # inf times 0 in G x
@pytest.mark.parametrize("where", ["c_v", "e", "G"])
@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_a_non_finite_problem_gives_no_point_never_a_non_finite_one(where, bad):
    """x is finite or None: the controller relies on it (no second check after the solve)."""
    qp = _problem(7, 0.0)
    getattr(qp, where)[0] = bad
    result = qp.solve(M_EQ)
    assert result.x is None or np.isfinite(result.x).all()
    assert not result.fast_path


@pytest.mark.parametrize("consistent", [True, False])
def test_dependent_equality_rows_are_dropped_and_counted(consistent):
    # e.g. the feet of legs without a hip yaw: their yaw rows are the base's, twice
    qp = _problem(7, 0.0)
    qp.E[1] = 2.0 * qp.E[0]
    qp.e[1] = 2.0 * qp.e[0] + (0.0 if consistent else 0.3)
    result = qp.solve(M_EQ)
    assert result.dependent_rows == 1 and result.x is not None
    residual = qp.E[:M_EQ] @ result.x - qp.e[:M_EQ]
    np.testing.assert_allclose(residual[2:], 0.0, atol=1e-9)  # the independent rows hold
    # one of the two dependent rows holds; the other only as far as it agrees with it
    assert min(abs(residual[0]), abs(residual[1])) < 1e-9
    # (row 0 kept: row 1 misses by 0.3; row 1 kept: row 0 misses by 0.15)
    expected = {0.0} if consistent else {0.3, 0.15}
    assert any(max(abs(residual[0]), abs(residual[1])) == pytest.approx(v, abs=1e-9) for v in expected)


def test_dependent_rows_on_the_fast_path_give_the_optimum_without_them():
    """The fast path's pivoted branch: the KKT point of the QP with the dependent row left out."""
    qp = _problem(7, 0.0)
    qp.E[1] = 2.0 * qp.E[0]
    qp.e[1] = 2.0 * qp.e[0]
    for lower, upper in ((qp.g_lo, qp.g_up), (qp.lb, qp.ub)):  # no inequality: the fast path's point
        lower[:], upper[:] = -np.inf, np.inf
    result = qp.solve(M_EQ)
    assert result.fast_path and result.dependent_rows == 1
    problem = qp.problem(M_EQ)
    keep = [0, *range(2, M_EQ)]
    E, e, n = qp.E[keep], qp.e[keep], NV + NF
    kkt = np.block([[problem.P, E.T], [E, np.zeros((len(keep), len(keep)))]])
    expected = np.linalg.solve(kkt, np.concatenate([-problem.q, e]))[:n]
    np.testing.assert_allclose(result.x, expected, atol=1e-9 * max(1.0, np.abs(expected).max()))


def test_problem_export_round_trips_the_two_sided_rows():
    # a hand-sized case, the expected matrices written out: nv = 2, n_f = 1, w_f = 0.5
    qp = WholeBodyQP(2, 1, 2, 2, force_weight=0.5)
    qp.H_vv[:] = [[2.0, 1.0], [1.0, 3.0]]
    qp.c_v[:] = [1.0, -1.0]
    qp.E[:] = [[1.0, 0.0, 2.0], [0.0, 1.0, 1.0]]
    qp.e[:] = [0.5, 7.0]  # the second row is not exported with m_eq = 1
    qp.G[:] = [[1.0, 2.0, 0.0], [0.0, 1.0, -1.0]]
    qp.g_lo[:] = [-1.0, -np.inf]  # row 1 is one-sided: no -G row for it
    qp.g_up[:] = [2.0, 3.0]
    qp.lb[:] = [-5.0, -5.0, 0.0]
    qp.ub[:] = [5.0, 5.0, np.inf]
    problem = qp.problem(1)
    P = np.array([[2.0, 1.0, 0.0], [1.0, 3.0, 0.0], [0.0, 0.0, 0.25]])  # blockdiag(H_vv, w_f^2 I)
    np.testing.assert_array_equal(problem.P, P)
    np.testing.assert_array_equal(problem.q, [1.0, -1.0, 0.0])  # [c_v; 0]
    # each finite upper bound as G x <= g_up, each finite lower bound as -G x <= -g_lo
    np.testing.assert_array_equal(problem.G, [[1.0, 2.0, 0.0], [0.0, 1.0, -1.0], [-1.0, -2.0, 0.0]])
    np.testing.assert_array_equal(problem.h, [2.0, 3.0, 1.0])
    np.testing.assert_array_equal(problem.A, [[1.0, 0.0, 2.0]])
    np.testing.assert_array_equal(problem.b, [0.5])
    np.testing.assert_array_equal(problem.lb, [-5.0, -5.0, 0.0])
    np.testing.assert_array_equal(problem.ub, [5.0, 5.0, np.inf])
    # copies: editing the export leaves the buffers alone
    problem.A[0, 0] = problem.b[0] = problem.lb[0] = problem.ub[0] = 99.0
    assert qp.E[0, 0] == 1.0 and qp.e[0] == 0.5 and qp.lb[0] == -5.0 and qp.ub[0] == 5.0
    # the structured solve's optimum is the exported problem's
    x = qp.solve(1).x
    reference = qpsolvers.solve_problem(qp.problem(1), solver="daqp").x
    np.testing.assert_allclose(x, reference, atol=1e-9)


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10_000))
def test_pinned_forces_stay_on_the_fast_path_at_the_optimum(seed):
    """A released foot's forces pinned at zero (bounds [0, 0]) are left out of the fast path's
    Schur complement: it still gives the whole QP's optimum, where before it always handed over
    to daqp (its point put force on the pinned variables)."""
    qp = _problem(seed, 0.0)
    pinned = slice(NV + 3, NV + NF)  # the second "foot": three force variables
    qp.lb[pinned] = qp.ub[pinned] = 0.0
    qp.force_free[pinned.start - NV:] = False
    # room around the new optimum: the rows' and the other bounds' ranges widened
    qp.g_lo[:] -= 1e3
    qp.g_up[:] += 1e3
    qp.lb[:NV] -= 1e3
    qp.ub[NV:pinned.start] += 1e3
    result = qp.solve(M_EQ)
    reference = _reference(qp, M_EQ)
    assert result.fast_path
    np.testing.assert_array_equal(result.x[pinned], 0.0)
    np.testing.assert_allclose(result.x, reference, atol=1e-6 * max(1.0, np.abs(reference).max()))


def _count_fast_tries(qp: WholeBodyQP, monkeypatch) -> list[int]:
    tries = [0]
    kkt = qp._kkt

    def counted(m_eq):
        tries[0] += 1
        return kkt(m_eq)

    monkeypatch.setattr(qp, "_kkt", counted)
    return tries


def test_the_fast_path_is_skipped_while_an_inequality_stays_active(monkeypatch):
    qp = _problem(11, 0.2)
    tries = _count_fast_tries(qp, monkeypatch)
    first = qp.solve(M_EQ)
    assert not first.fast_path and first.x is not None and tries[0] == 1
    second = qp.solve(M_EQ)  # the same problem: daqp directly, the same optimum
    assert tries[0] == 1
    np.testing.assert_allclose(second.x, first.x, atol=1e-9)
    # the cut removed: daqp (skipping the fast path once more) finds no inequality active, so
    # the next solve takes the fast path again
    loose = _problem(11, 0.0)
    qp.g_up[:], qp.ub[:] = loose.g_up, loose.ub
    third = qp.solve(M_EQ)
    assert tries[0] == 1 and not third.fast_path
    np.testing.assert_allclose(third.x, loose.solve(M_EQ).x, atol=1e-6)
    fourth = qp.solve(M_EQ)
    assert fourth.fast_path and tries[0] == 2


def test_a_skipped_fast_path_is_retried_when_daqp_finds_no_solution(monkeypatch):
    """Dependent equality rows after a skip: the solve is repeated the full way (rows dropped)."""
    qp = _problem(7, 0.2)
    tries = _count_fast_tries(qp, monkeypatch)
    assert qp.solve(M_EQ).x is not None and tries[0] == 1
    qp.E[1] = 2.0 * qp.E[0]
    qp.e[1] = 2.0 * qp.e[0] + 0.3  # inconsistent: daqp alone finds no solution
    fresh = _problem(7, 0.2)
    fresh.E[:M_EQ], fresh.e[:M_EQ] = qp.E[:M_EQ], qp.e[:M_EQ]
    expected = fresh.solve(M_EQ)
    result = qp.solve(M_EQ)
    assert tries[0] == 2 and result.dependent_rows == 1 == expected.dependent_rows
    np.testing.assert_allclose(result.x, expected.x, atol=1e-9)


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10_000), st.sampled_from([slice(0, 3), slice(5, 10)]), st.booleans())
def test_the_reduced_qp_gives_the_whole_qps_optimum(seed, deferred, pin):
    """daqp first solves without the deferred rows (and the pinned forces); its point is kept only
    when it satisfies the deferred rows, else the whole QP is solved: the optimum either way."""
    qp = _problem(seed, 0.2)  # rows 0-2 and a bound cut: active at the optimum
    if pin:
        qp.lb[NV + 3:] = qp.ub[NV + 3:] = 0.0
        qp.force_free[3:] = False
    qp.deferred_rows = deferred
    whole = []
    solve = qp._daqp_solver.solve
    qp._daqp_solver.solve = lambda data: whole.append(1) or solve(data)
    result = qp.solve(M_EQ)
    reference = _reference(qp, M_EQ)
    if reference is None:
        assert result.x is None
        return
    np.testing.assert_allclose(result.x, reference, atol=1e-6 * max(1.0, np.abs(reference).max()))
    g = qp.G[deferred] @ result.x
    assert (g <= qp.g_up[deferred] + 1e-6).all() and (g >= qp.g_lo[deferred] - 1e-6).all()
    # the whole QP is solved exactly when the optimum without the deferred rows violates them
    # (always when they are the cut rows)
    lo, up = qp.g_lo.copy(), qp.g_up.copy()
    qp.g_lo[deferred], qp.g_up[deferred] = -np.inf, np.inf
    relaxed = _reference(qp, M_EQ)
    qp.g_lo[:], qp.g_up[:] = lo, up
    g = qp.G[deferred] @ relaxed
    violated = bool((g > up[deferred] + 1e-5).any() or (g < lo[deferred] - 1e-5).any())
    # with forces pinned, the QP without them alone (every row in) comes before the whole one: it is
    # the whole QP's optimum whenever there is one
    assert whole == ([1] if violated and not pin else [])


def test_deferred_rows_cut_at_the_optimum_send_the_solve_to_the_whole_qp():
    """The path the property above takes only when the left-out rows bind: here they do (the cut rows
    of this problem; in some random problems they do not, e.g. seed 266)."""
    qp = _problem(7, 0.2)
    qp.deferred_rows = slice(0, 3)
    whole = []
    solve = qp._daqp_solver.solve
    qp._daqp_solver.solve = lambda data: whole.append(1) or solve(data)
    result = qp.solve(M_EQ)
    reference = _reference(qp, M_EQ)
    assert reference is not None and whole == [1]
    np.testing.assert_allclose(result.x, reference, atol=1e-6 * max(1.0, np.abs(reference).max()))


def test_the_reduced_qps_point_is_checked_against_every_left_out_row():
    """A row over pinned forces only is left out of the reduced QP; were it unmet at zero (here it
    asks the pinned force for 1 N), the reduced point is not taken: the whole QP finds no solution."""
    qp = _problem(3, 0.0)
    qp.deferred_rows = slice(8, 10)
    pinned = NV + NF - 1
    qp.lb[pinned] = qp.ub[pinned] = 0.0
    qp.force_free[-1] = False
    qp.G[4] = 0.0
    qp.G[4, pinned] = 1.0
    qp.g_lo[4], qp.g_up[4] = 1.0, 2.0
    result = qp.solve(M_EQ)
    assert result.x is None and result.status < 0


def test_with_forces_pinned_the_qp_without_them_answers_where_daqp_fails_on_the_whole_qp():
    """daqp can report no solution on the whole QP where there is one (a released foot's pinned forces
    make a degenerate vertex: seen after pushes while walking); the QP without the pinned forces, every
    row kept, is the whole QP's and is solved before it."""
    qp = _problem(4, 0.2)
    qp.deferred_rows = slice(0, 3)  # the cut rows: the first reduced QP's point violates them
    qp.lb[NV + 3:] = qp.ub[NV + 3:] = 0.0
    qp.force_free[3:] = False
    qp.use_force_space = False
    whole, reduced = [], []
    qp._daqp_solver.solve = lambda data: whole.append(1) or QPResult(None, -1, 0, 0.0)  # as daqp did
    solve = qp._reduced.solve
    qp._reduced.solve = lambda *args: reduced.append(args[-1]) or solve(*args)
    result = qp.solve(M_EQ)
    reference = _reference(qp, M_EQ)
    # the deferred rows cut the first reduced QP's point: the second (every row) gives the optimum
    assert reference is not None and reduced == [True, False] and whole == [] and result.x is not None
    np.testing.assert_allclose(result.x, reference, atol=1e-6 * max(1.0, np.abs(reference).max()))
    np.testing.assert_array_equal(result.x[NV + 3:], 0.0)
