"""ComTask: ``e = p_WC - p_target`` in W, ``J = J_com``, ``Jdot_com v`` (both code paths), its rows."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mbctl.control.exceptions import TaskSetupError
from mbctl.control.tasks import AccelerationGains, ComTask, DynamicsState, KinematicState, Task
from mbctl.control.tasks.frame import world_vector
from tests.control.tasks.conftest import (
    MODELS,
    acceleration_objective,
    acceleration_rows,
    expected_acceleration_objective,
    expected_velocity_objective,
    fd_drift,
    fd_jacobian,
    inf_norm,
    kinematic_error,
    random_q,
    velocity_objective,
    velocity_rows,
)

IDS = [model.name for model in MODELS]
SEEDS = st.integers(min_value=0, max_value=2**32 - 1)


def _com_by_hand(model: pin.Model, q: np.ndarray) -> np.ndarray:
    """``sum_i m_i p_WCi / sum_i m_i`` over the bodies, from the joint placements alone."""
    data = model.createData()
    pin.forwardKinematics(model, data, q)
    masses = [model.inertias[j].mass for j in range(1, model.njoints)]
    points = [data.oMi[j].act(model.inertias[j].lever) for j in range(1, model.njoints)]
    return np.average(points, axis=0, weights=masses)


@pytest.mark.parametrize("model", MODELS, ids=IDS)
def test_the_error_is_the_centre_of_mass_minus_the_target(model):
    q = random_q(model, np.random.default_rng(4))
    state = KinematicState(model, q)
    task = ComTask()
    with pytest.raises(TaskSetupError, match="com: no target set"):
        task.compute_error(state)
    task.set_target_from_state(state)
    np.testing.assert_array_equal(task.compute_error(state), np.zeros(3))
    p_WC = _com_by_hand(model, q)
    np.testing.assert_allclose(task.target, p_WC, atol=1e-15)
    task.set_target(p_WC - [0.02, 0.0, -0.01])
    np.testing.assert_allclose(task.compute_error(state), [0.02, 0.0, -0.01], atol=1e-15)
    # a free axis (cost 0, here the height) is ignored by the residual
    task.set_cost([1.0, 1.0, 0.0])
    assert task.residual(state).position_m == pytest.approx(0.02, abs=1e-15)


@pytest.mark.parametrize("model", MODELS, ids=IDS)
@settings(deadline=None, max_examples=15)
@given(seed=SEEDS)
def test_the_jacobian_matches_finite_differences_on_the_manifold(model, seed):
    rng = np.random.default_rng(seed)
    q = random_q(model, rng, 1.0)
    state = KinematicState(model, q)
    task = ComTask()
    task.set_target(rng.standard_normal(3))
    e, J = task.error_and_jacobian(state)
    assert J.shape == (3, model.nv)
    err = inf_norm(J - fd_jacobian(kinematic_error(task, model), model, q))
    assert err < 1e-8, f"|J - J_fd|_inf = {err:.2e}"


@pytest.mark.parametrize("model", MODELS, ids=IDS)
@settings(deadline=None, max_examples=15)
@given(seed=SEEDS, centroidal_first=st.booleans())
def test_the_drift_is_the_time_derivative_of_the_jacobian_along_v(model, seed, centroidal_first):
    # a free-flyer root reads Jdot_com v off the root's bias forces unless the centroidal drift is
    # already computed (then its linear rows); a fixed base always takes Pinocchio's pass
    rng = np.random.default_rng(seed)
    q, v = random_q(model, rng, 1.0), rng.standard_normal(model.nv)
    state = DynamicsState(model, q, v)
    if centroidal_first:
        state.centroidal_drift()
    J, drift = ComTask().jacobian_and_drift(state)
    fd = fd_drift(ComTask(), model, q, v)
    err = inf_norm(drift - fd)
    assert err < 1e-7 * max(1.0, inf_norm(fd)), f"|Jdot v - fd|_inf = {err:.2e}"


@pytest.mark.parametrize("model", MODELS, ids=IDS)
def test_the_rows_and_the_stacked_objective_follow_the_error_and_jacobian(model):
    rng = np.random.default_rng(10)
    q, v = random_q(model, rng), rng.standard_normal(model.nv)
    task = ComTask(cost=[3.0, 1.0, 0.0], gain=0.5, lm_damping=0.2, servo=AccelerationGains(4.0, 1.1))
    task.set_target(rng.standard_normal(3), v=rng.standard_normal(3), a=rng.standard_normal(3))
    state = KinematicState(model, q)
    e, J = task.error_and_jacobian(state)
    # velocity level: the active rows (x, y: the free height is left out), unweighted, not negated
    assert task.active_rows().tolist() == [0, 1]
    J_rows, e_rows = velocity_rows(task, state)
    np.testing.assert_allclose(J_rows, J[:2], atol=1e-15)
    np.testing.assert_allclose(e_rows, e[:2], atol=1e-15)
    W_t, r_t = np.zeros((3, model.nv)), np.zeros(3)
    mu = task.write_qp_rows(state, W_t, r_t)  # the fast path
    np.testing.assert_allclose(W_t, task.cost[:, None] * J, atol=1e-15)
    np.testing.assert_allclose(r_t, -0.5 * task.cost * e, atol=1e-15)
    H, c, mu_stack = velocity_objective(task, state)
    H_ref, c_ref, mu_ref = expected_velocity_objective(task, e, J)
    np.testing.assert_allclose(H, H_ref, atol=1e-13)
    np.testing.assert_allclose(c, c_ref, atol=1e-13)
    assert mu == pytest.approx(mu_ref, rel=1e-13) and mu_stack == pytest.approx(mu_ref, rel=1e-13)
    # acceleration level: a_des = a_ref - kp e + kd (v_ref - J v)
    dyn = DynamicsState(model, q, v)
    J_a, drift = task.jacobian_and_drift(dyn)
    np.testing.assert_allclose(J_a, J, atol=1e-15)
    a_des = task.a_ref - 16.0 * e + 2 * 1.1 * 4.0 * (task.v_ref - J_a @ v)
    np.testing.assert_allclose(task.desired_acceleration(dyn, J_a), a_des, atol=1e-12)
    W_a, r_a = acceleration_rows(task, dyn)  # the fast path
    np.testing.assert_allclose(W_a, task.cost[:, None] * J_a, atol=1e-15)
    np.testing.assert_allclose(r_a, task.cost * (a_des - drift), atol=1e-12)
    W_g, r_g = np.zeros((3, model.nv)), np.zeros(3)
    Task.write_acceleration_rows(task, dyn, W_g, r_g)
    np.testing.assert_allclose(r_a, r_g, atol=1e-12)
    H_a, c_a = acceleration_objective(task, dyn)
    H_ref, c_ref = expected_acceleration_objective(task, J_a, drift, a_des)
    np.testing.assert_allclose(H_a, H_ref, atol=1e-12)
    np.testing.assert_allclose(c_a, c_ref, atol=1e-10)


@given(st.lists(st.one_of(st.floats(), st.integers(-10**6, 10**6), st.booleans()), max_size=4),
       st.sampled_from([list, tuple]))
def test_a_target_of_plain_numbers_is_taken_as_its_array_would_be(values, kind):
    """world_vector's check of plain numbers before converting: the same vector or the same error."""
    arr = np.array(values, dtype=float)
    if arr.shape == (3,) and np.isfinite(arr).all():
        np.testing.assert_array_equal(world_vector(kind(values), "com", "target"), arr)
    else:
        with pytest.raises(TaskSetupError, match=r"com: target must be a finite \(3,\) vector"):
            world_vector(kind(values), "com", "target")


def test_bad_targets_are_named():
    task = ComTask()
    with pytest.raises(TaskSetupError, match=r"com: target position \[m\] must be a finite \(3,\)"):
        task.set_target([0.0, 0.0])
    with pytest.raises(TaskSetupError, match=r"com: target acceleration \[m/s\^2\]"):
        task.set_target(np.zeros(3), a=[0.0, np.inf, 0.0])
    with pytest.raises(TaskSetupError, match="no target set"):
        _ = task.target
