"""The whole-body QP solved in its contact forces alone (control/wbc/force_space.py) against the whole QP.

Problems of the controller's structure: force columns only in the last equality rows (the base's
dynamics), rows over the forces alone (friction-like) and rows with vdot in them (torque-like).
"""

from __future__ import annotations

import numpy as np
import pytest
import qpsolvers
from hypothesis import given, settings
from hypothesis import strategies as st

from mbctl.control.wbc.force_space import ForceSpace
from mbctl.control.wbc.qp import WholeBodyQP

NV, NF, M_FEET, M_U = 8, 6, 3, 3
M_EQ = M_FEET + M_U
N_V_ROWS, N_F_ROWS = 4, 6  # rows with vdot (first), rows over the forces alone


def _problem(seed: int) -> WholeBodyQP:
    """A random QP of the controller's structure with room around its equality-constrained optimum."""
    rng = np.random.default_rng(seed)
    qp = WholeBodyQP(NV, NF, N_V_ROWS + N_F_ROWS, M_EQ, force_weight=0.3, m_force=M_U)
    W = rng.normal(size=(NV + 2, NV))
    qp.H_vv[:] = W.T @ W + 1e-3 * np.eye(NV)
    qp.c_v[:] = rng.normal(size=NV)
    qp.E[:M_FEET, :NV] = rng.normal(size=(M_FEET, NV))
    qp.E[M_FEET:M_EQ] = rng.normal(size=(M_U, NV + NF))
    qp.e[:M_EQ] = rng.normal(size=M_EQ)
    qp.G[:N_V_ROWS] = rng.normal(size=(N_V_ROWS, NV + NF))
    qp.G[N_V_ROWS:, NV:] = rng.normal(size=(N_F_ROWS, NF))
    x_free = qp.solve(M_EQ).x  # the fast path: nothing bounded yet
    g = qp.G @ x_free
    qp.g_lo[:], qp.g_up[:] = g - 1.0, g + 1.0
    qp.lb[:], qp.ub[:] = x_free - 1.0, x_free + 1.0
    qp.deferred_rows = slice(0, N_V_ROWS)
    return qp


def _cut(qp: WholeBodyQP, row: int, by: float = 0.3) -> None:
    """Move row ``row``'s upper bound ``by`` past the equality-constrained optimum (it becomes active)."""
    x_free = _problem_free_point(qp)
    qp.g_up[row] = qp.G[row] @ x_free - by


def _problem_free_point(qp: WholeBodyQP) -> np.ndarray:
    lo, up = qp._lo.copy(), qp._up.copy()
    qp._lo[:], qp._up[:] = -np.inf, np.inf
    x = qp.solve(M_EQ).x
    qp._lo[:], qp._up[:] = lo, up
    return x


def _reference(qp: WholeBodyQP) -> np.ndarray:
    solution = qpsolvers.solve_problem(qp.problem(M_EQ), solver="daqp")
    assert solution.found
    return solution.x


def _spy(qp: WholeBodyQP, monkeypatch) -> list[bool]:
    """Each force-space solve: whether it gave a point (appended per call)."""
    calls: list[bool] = []
    solve = qp._force.solve

    def counted(*args):
        out = solve(*args)
        calls.append(out is not None)
        return out

    monkeypatch.setattr(qp._force, "solve", counted)
    return calls


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 10_000), st.integers(N_V_ROWS, N_V_ROWS + N_F_ROWS - 1), st.booleans())
def test_a_force_row_active_gives_the_whole_qps_optimum_from_the_forces_alone(seed, row, pin):
    qp = _problem(seed)
    if pin:  # the second "foot" released: its forces pinned at zero, as the controller does
        qp.lb[NV + 3:] = qp.ub[NV + 3:] = 0.0
        qp.force_free[3:] = False
        qp.g_lo[:] -= 1e3  # (room: the pinned forces move the optimum)
        qp.g_up[:] += 1e3
        qp.lb[:NV + 3] -= 1e3
        qp.ub[:NV + 3] += 1e3
    _cut(qp, row)
    reference = _reference(qp)
    result = qp.solve(M_EQ)
    np.testing.assert_allclose(result.x, reference, atol=1e-6 * max(1.0, np.abs(reference).max()))
    assert not result.fast_path and result.status == 1
    # the rows over the forces alone are its constraints: so its point is the optimum unless a bound
    # on vdot or a row with vdot in it binds there, when the whole QP decides
    at_v = np.concatenate([reference[:NV], qp.G[:N_V_ROWS] @ reference])
    lo_v = np.concatenate([qp.lb[:NV], qp.g_lo[:N_V_ROWS]])
    up_v = np.concatenate([qp.ub[:NV], qp.g_up[:N_V_ROWS]])
    v_binds = bool((np.minimum(at_v - lo_v, up_v - at_v) < 1e-6).any())
    assert (qp.Gx is not None) == (not v_binds)
    if pin:
        np.testing.assert_array_equal(result.x[NV + 3:], 0.0)
    if qp.Gx is not None:  # the solve's G x, as the fast path gives it (the controller's torques)
        np.testing.assert_allclose(qp.Gx, qp.G @ result.x, rtol=0.0, atol=1e-12)


def test_an_acceleration_bound_active_skips_the_force_space_until_none_is(monkeypatch):
    qp = _problem(5)
    _cut(qp, N_V_ROWS + 1)
    calls = _spy(qp, monkeypatch)
    free = qp.solve(M_EQ)
    assert calls == [True] and qp.Gx is not None and not free.fast_path
    j, saved = 2, (qp.lb[2], qp.ub[2])
    qp.ub[2] = free.x[2] - 0.05  # cuts the force space's point (the same again: no vdot bound in it)
    qp.lb[2] = min(qp.lb[2], qp.ub[2] - 1.0)
    held = qp.solve(M_EQ)  # so the whole QP solves it
    assert calls == [True, True] and qp.Gx is None and qp._skip_force
    np.testing.assert_allclose(held.x, _reference(qp), atol=1e-6)
    assert held.x[j] == pytest.approx(qp.ub[j], abs=1e-7)
    again = qp.solve(M_EQ)  # the bound still binds: the force space is not tried
    assert calls == [True, True] and qp._skip_force
    np.testing.assert_allclose(again.x, held.x, atol=1e-9)
    qp.lb[j], qp.ub[j] = saved
    qp.solve(M_EQ)  # daqp once more, which finds no bound on vdot active
    assert calls == [True, True] and not qp._skip_force
    qp.solve(M_EQ)
    assert calls == [True, True, True] and qp.Gx is not None


def test_dependent_equality_rows_are_left_to_the_whole_qp(monkeypatch):
    qp = _problem(2)
    _cut(qp, N_V_ROWS)
    qp.E[1] = 2.0 * qp.E[0]  # dependent (the feet's rows of legs that cannot yaw apart)
    qp.e[1] = 2.0 * qp.e[0]
    calls = _spy(qp, monkeypatch)
    result = qp.solve(M_EQ)
    assert result.dependent_rows == 1 and calls == []  # the rows dropped: the general path
    np.testing.assert_allclose(result.x, _reference(qp), atol=1e-6)
    space = ForceSpace(NV, qp.E, qp.e, qp.G, qp._lo, qp._up, M_U)  # directly: declines them
    b = qp._factor(M_EQ)
    assert b is not None
    assert space.solve(b.Z, qp._L, M_EQ, np.ones(NF), 0.3, np.empty(NV + NF)) is None


@pytest.mark.parametrize("use", [True, False])
def test_the_switch_turns_the_force_space_off(use, monkeypatch):
    qp = _problem(8)
    _cut(qp, N_V_ROWS + 2)
    qp.use_force_space = use
    calls = _spy(qp, monkeypatch)
    result = qp.solve(M_EQ)
    assert (calls == [True]) == use and (qp.Gx is not None) == use
    np.testing.assert_allclose(result.x, _reference(qp), atol=1e-6)
