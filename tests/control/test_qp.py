"""The QP floor (mbctl.control.qp): daqp's packing, the infinity convention, the result, the errors.

Tiny QPs whose optimum is known in closed form, solved by daqp directly and through qpsolvers.
"""

from __future__ import annotations

import numpy as np
import pytest
import qpsolvers

from mbctl.control.exceptions import IKInfeasible, WBCInfeasible
from mbctl.control.qp import (
    CONTRADICTORY,
    INFEASIBLE,
    NOT_FOUND,
    OPTIMAL,
    QP_INFINITY,
    QPData,
    QPResult,
    QPSolver,
    infeasible_error,
    solve_qpsolvers,
)

INF = np.inf


def _solve(qp: QPData, backend: str) -> QPResult:
    """daqp called directly ("daqp"), or daqp through qpsolvers ("qpsolvers")."""
    if backend == "daqp":
        return QPSolver(len(qp.c)).solve(qp)
    return solve_qpsolvers(qp, "daqp")


def _nearest(target: list[float], **constraints) -> QPData:
    """min 1/2 |x - target|^2: the projection of ``target`` onto the constraints."""
    n = len(target)
    return QPData(np.eye(n), -np.asarray(target, dtype=float), **constraints)


@pytest.mark.parametrize("backend", ["daqp", "qpsolvers"])
def test_a_tiny_qp_gives_its_known_optimum_and_the_result_type(backend):
    # min 1/2 |x - (1, 1)|^2 s.t. x_0 + x_1 <= 1: the projection onto the half-plane, (0.5, 0.5)
    result = _solve(_nearest([1.0, 1.0], G=np.array([[1.0, 1.0]]), h=np.array([1.0])), backend)
    assert isinstance(result, QPResult)
    np.testing.assert_allclose(result.x, [0.5, 0.5], atol=1e-12)
    assert result.status == OPTIMAL
    assert result.solve_time_s >= 0.0
    assert result.iterations >= 1 if backend == "daqp" else result.iterations == -1
    assert (result.fast_path, result.dependent_rows) == (False, 0)


@pytest.mark.parametrize("backend", ["daqp", "qpsolvers"])
@pytest.mark.parametrize("infinity", [INF, QP_INFINITY, 1e40])
def test_bounds_and_rows_with_infinite_sides(backend, infinity):
    # target (3, -3, 0): x_0 <= 1 (its lower side absent), x_1 >= -2 (its upper side absent),
    # 0.5 <= x_2 - x_0 (row with only a lower side), x_0 + x_1 + x_2 <= inf (a row with neither)
    qp = _nearest(
        [3.0, -3.0, 0.0],
        lb=np.array([-infinity, -2.0, -infinity]), ub=np.array([1.0, infinity, infinity]),
        G=np.array([[-1.0, 0.0, 1.0], [1.0, 1.0, 1.0]]), h=np.array([infinity, infinity]),
        h_lo=np.array([0.5, -infinity]),
    )
    result = _solve(qp, backend)
    # x_1 = -2 at its bound; x_0, x_2 project (3, 0) onto x_0 <= 1 and x_2 >= x_0 + 0.5: (1, 1.5)
    # is on both with the gradient (2, -1.5) in their cone, so it is the optimum
    np.testing.assert_allclose(result.x, [1.0, -2.0, 1.5], atol=1e-9)
    assert result.status == OPTIMAL


@pytest.mark.parametrize("backend", ["daqp", "qpsolvers"])
def test_equality_rows(backend):
    # x_0 = x_1 and x_0 + x_1 <= 1 from target (1, 0): on the line x_0 = x_1, (0.5, 0.5) is nearest
    result = _solve(_nearest([1.0, 0.0], G=np.array([[1.0, 1.0]]), h=np.array([1.0]),
                             A=np.array([[1.0, -1.0]]), b=np.array([0.0])), backend)
    np.testing.assert_allclose(result.x, [0.5, 0.5], atol=1e-9)


def test_the_buffers_follow_each_calls_rows():
    """One solver, problems of different row counts and kinds in turn: each gets its own answer."""
    solver = QPSolver(2)
    cases = [
        (dict(A=np.array([[1.0, -1.0]]), b=np.array([0.0])), [0.5, 0.5]),  # the equality
        (dict(G=np.array([[1.0, -1.0]]), h=np.array([0.0])), [0.5, 0.5]),  # the same row, an inequality
        (dict(G=np.array([[-1.0, 1.0]]), h=np.array([0.0])), [1.0, 0.0]),  # inactive
        (dict(lb=np.array([-INF, 0.2]), ub=np.array([0.8, INF])), [0.8, 0.2]),  # bounds only
        (dict(lb=np.array([-INF, 0.2]), ub=np.array([0.8, INF]), G=np.ones((3, 2)), h=np.full(3, 0.5),
              A=np.array([[1.0, 0.0]]), b=np.array([0.1])), [0.1, 0.2]),  # more rows: the buffers grow
        (dict(), [1.0, 0.0]),  # nothing
    ]
    for constraints, expected in cases * 2:
        np.testing.assert_allclose(solver.solve(_nearest([1.0, 0.0], **constraints)).x, expected, atol=1e-9)


@pytest.mark.parametrize("backend", ["daqp", "qpsolvers"])
def test_an_infeasible_qp_raises_the_callers_error_naming_the_status(backend):
    # x_0 <= -1 and x_0 >= 1, as two rows
    qp = _nearest([0.0, 0.0], G=np.array([[1.0, 0.0], [-1.0, 0.0]]), h=np.array([-1.0, -1.0]))
    result = _solve(qp, backend)
    assert result.x is None
    status = INFEASIBLE if backend == "daqp" else NOT_FOUND
    assert result.status == status
    error = infeasible_error(IKInfeasible, "the tiny QP has no solution", "Relax a row.", qp, result, "daqp")
    assert type(error) is IKInfeasible
    text = "infeasible" if backend == "daqp" else "no finite solution found"
    assert str(error) == f"the tiny QP has no solution (daqp: exit flag {status} ({text})). Relax a row."
    assert isinstance(error.problem, qpsolvers.Problem) and error.solver == "daqp"
    assert error.result.found is False and error.result.extras["status"] == status
    np.testing.assert_array_equal(error.problem.h, [-1.0, -1.0])
    with pytest.raises(IKInfeasible, match="the tiny QP has no solution"):
        raise error


@pytest.mark.parametrize("backend", ["daqp", "qpsolvers"])
def test_contradictory_bounds_are_named_with_their_values(backend):
    qp = _nearest([0.0, 0.0], lb=np.array([1.0, 0.0]), ub=np.array([-1.0, 2.0]))
    result = _solve(qp, backend)
    assert result.x is None and result.status == CONTRADICTORY
    error = infeasible_error(WBCInfeasible, "the tiny QP has no solution", "Relax a bound.", qp, result,
                             "daqp", time_s=0.5)
    assert type(error) is WBCInfeasible and error.time_s == 0.5
    assert str(error) == ("the tiny QP has no solution (daqp: exit flag -100 (contradictory bounds); lower "
                          "above upper at x[0]: [1.0] > [-1.0]). Relax a bound.")
    # and on a two-sided row
    qp = _nearest([0.0, 0.0], G=np.array([[1.0, 1.0]]), h=np.array([0.0]), h_lo=np.array([0.25]))
    result = _solve(qp, backend)
    assert result.status == CONTRADICTORY
    assert "lower above upper at row[0]: [0.25] > [0.0]" in str(
        infeasible_error(IKInfeasible, "x", "y", qp, result, "daqp"))


@pytest.mark.filterwarnings("ignore:invalid value:RuntimeWarning")
@pytest.mark.parametrize("where", ["c", "G", "h"])
@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_a_non_finite_problem_gives_no_point_never_a_non_finite_one(where, bad):
    data = dict(c=np.array([-1.0, -1.0]), G=np.array([[1.0, 1.0]]), h=np.array([1.0]))
    data[where] = data[where].copy()
    data[where].flat[0] = bad
    result = QPSolver(2).solve(QPData(np.eye(2), **data))
    assert result.x is None or np.isfinite(result.x).all()
    if where == "h" and bad == np.inf:  # an absent upper bound: the unconstrained optimum
        np.testing.assert_allclose(result.x, [1.0, 1.0])
    elif result.x is None:
        assert result.status < 0


def test_problem_export_copies_and_splits_two_sided_rows():
    G = np.array([[1.0, 2.0], [0.0, 1.0], [3.0, 0.0]])
    qp = QPData(np.eye(2), np.zeros(2), np.array([-1.0, -INF]), np.array([1.0, 2.0]), G,
                h=np.array([2.0, QP_INFINITY, 5.0]), h_lo=np.array([-1.0, 0.0, -INF]))
    problem = qp.problem()
    # finite upper sides as G x <= h, then finite lower sides as -G x <= -h_lo
    np.testing.assert_array_equal(problem.G, [[1.0, 2.0], [3.0, 0.0], [-1.0, -2.0], [0.0, -1.0]])
    np.testing.assert_array_equal(problem.h, [2.0, 5.0, 1.0, 0.0])
    problem.lb[0] = problem.P[0, 0] = 99.0
    assert qp.lb[0] == -1.0 and qp.H[0, 0] == 1.0
    # one-sided rows go as they are
    one_sided = QPData(np.eye(2), np.zeros(2), G=G, h=np.array([1.0, 2.0, 3.0])).problem()
    np.testing.assert_array_equal(one_sided.G, G)
