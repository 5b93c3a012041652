"""FramePositionTask: ``e = p_WF - p_WT`` in W, ``J_e = R_WF J_F[:3]``, the classical drift, its rows."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mbctl.control.exceptions import TaskSetupError
from mbctl.control.tasks import AccelerationGains, DynamicsState, FramePositionTask, KinematicState, Task
from tests.control.tasks.conftest import (
    ARM,
    FLOATING,
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

CASES = [(ARM, "tip"), (FLOATING, "hand"), (FLOATING, "foot"), (FLOATING, "chest")]
IDS = [f"{model.name}-{frame}" for model, frame in CASES]
SEEDS = st.integers(min_value=0, max_value=2**32 - 1)


@pytest.mark.parametrize(("model", "frame"), CASES, ids=IDS)
def test_the_error_is_the_frame_origin_minus_the_target_in_the_world(model, frame):
    state = KinematicState(model, random_q(model, np.random.default_rng(0)))
    task = FramePositionTask(frame, model)
    with pytest.raises(TaskSetupError, match="no target set"):
        task.compute_error(state)
    task.set_target_from_state(state)
    np.testing.assert_array_equal(task.compute_error(state), np.zeros(3))
    p_WF = state.frame_pose(state.frame_id(frame)).translation
    offset_W = np.array([0.1, -0.2, 0.05])
    task.set_target(p_WF - offset_W)
    np.testing.assert_allclose(task.compute_error(state), offset_W, atol=1e-15)
    # an SE3 target: its translation only (any rotation is ignored)
    task.set_target(pin.SE3(pin.exp3(np.array([0.3, 0.2, -1.0])), p_WF + offset_W))
    np.testing.assert_allclose(task.compute_error(state), -offset_W, atol=1e-15)
    assert task.residual(state).position_m == pytest.approx(np.linalg.norm(offset_W), abs=1e-15)
    assert task.residual(state).orientation_rad is None


@pytest.mark.parametrize(("model", "frame"), CASES, ids=IDS)
@settings(deadline=None, max_examples=15)
@given(seed=SEEDS)
def test_the_jacobian_matches_finite_differences_on_the_manifold(model, frame, seed):
    rng = np.random.default_rng(seed)
    q = random_q(model, rng, 1.0)
    state = KinematicState(model, q)
    task = FramePositionTask(frame, model)
    task.set_target(rng.standard_normal(3))
    e, J = task.error_and_jacobian(state)
    assert J.shape == (3, model.nv)
    np.testing.assert_array_equal(e, task.compute_error(state))
    np.testing.assert_array_equal(J, task.compute_jacobian(state))
    err = inf_norm(J - fd_jacobian(kinematic_error(task, model), model, q))
    assert err < 1e-8, f"|J - J_fd|_inf = {err:.2e}"


@pytest.mark.parametrize(("model", "frame"), CASES, ids=IDS)
@settings(deadline=None, max_examples=15)
@given(seed=SEEDS)
def test_the_drift_is_the_time_derivative_of_the_jacobian_along_v(model, frame, seed):
    rng = np.random.default_rng(seed)
    q, v = random_q(model, rng, 1.0), rng.standard_normal(model.nv)
    task = FramePositionTask(frame, model)
    J, drift = task.jacobian_and_drift(DynamicsState(model, q, v))
    # the acceleration-level Jacobian is the IK one (world-aligned linear rows)
    np.testing.assert_allclose(J, task.compute_jacobian(KinematicState(model, q)), atol=1e-14)
    fd = fd_drift(task, model, q, v)
    err = inf_norm(drift - fd)
    assert err < 1e-7 * max(1.0, inf_norm(fd)), f"|Jdot v - fd|_inf = {err:.2e}"


@pytest.mark.parametrize(("model", "frame"), CASES, ids=IDS)
def test_the_rows_and_the_stacked_objective_follow_the_error_and_jacobian(model, frame):
    rng = np.random.default_rng(4)
    q, v = random_q(model, rng), rng.standard_normal(model.nv)
    task = FramePositionTask(frame, model, cost=[2.0, 0.0, 0.5], gain=0.7, lm_damping=0.3,
                             servo=AccelerationGains(8.0, 0.6))
    task.set_target(rng.standard_normal(3), v=rng.standard_normal(3), a=rng.standard_normal(3))
    # velocity level: the active rows (x and z), unweighted and not negated
    state = KinematicState(model, q)
    e, J = task.error_and_jacobian(state)
    assert task.active_rows().tolist() == [0, 2]
    J_rows, e_rows = velocity_rows(task, state)
    np.testing.assert_allclose(J_rows, J[[0, 2]], atol=1e-15)
    np.testing.assert_allclose(e_rows, e[[0, 2]], atol=1e-15)
    W_t, r_t = np.zeros((3, model.nv)), np.zeros(3)
    mu = task.write_qp_rows(state, W_t, r_t)
    np.testing.assert_allclose(W_t, task.cost[:, None] * J, atol=1e-15)
    np.testing.assert_allclose(r_t, -0.7 * task.cost * e, atol=1e-15)
    H, c, mu_stack = velocity_objective(task, state)
    H_ref, c_ref, mu_ref = expected_velocity_objective(task, e, J)
    np.testing.assert_allclose(H, H_ref, atol=1e-13)
    np.testing.assert_allclose(c, c_ref, atol=1e-13)
    assert mu == pytest.approx(mu_ref, rel=1e-13) and mu_stack == pytest.approx(mu_ref, rel=1e-13)
    # acceleration level: a_des = a_ref - kp e + kd (v_ref - J v), all in W
    dyn = DynamicsState(model, q, v)
    J_a, drift = task.jacobian_and_drift(dyn)
    a_des = task.a_ref_W - 64.0 * e + 2 * 0.6 * 8.0 * (task.v_ref_W - J_a @ v)
    np.testing.assert_allclose(task.desired_acceleration(dyn, J_a), a_des, atol=1e-12)
    W_a, r_a = acceleration_rows(task, dyn)
    np.testing.assert_allclose(W_a, task.cost[:, None] * J_a, atol=1e-15)
    np.testing.assert_allclose(r_a, task.cost * (a_des - drift), atol=1e-12)
    W_g, r_g = np.zeros((3, model.nv)), np.zeros(3)
    Task.write_acceleration_rows(task, dyn, W_g, r_g)
    np.testing.assert_allclose(r_a, r_g, atol=1e-12)
    H_a, c_a = acceleration_objective(task, dyn)
    H_ref, c_ref = expected_acceleration_objective(task, J_a, drift, a_des)
    np.testing.assert_allclose(H_a, H_ref, atol=1e-12)
    np.testing.assert_allclose(c_a, c_ref, atol=1e-10)


def test_a_bad_target_is_named():
    task = FramePositionTask("tip", ARM)
    with pytest.raises(TaskSetupError, match=r"tip position: target must be a finite \(3,\) position"):
        task.set_target([0.0, np.nan, 0.0])
    with pytest.raises(TaskSetupError, match=r"target velocity \[m/s\]"):
        task.set_target(np.zeros(3), v=[1.0, 2.0])
