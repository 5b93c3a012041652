"""FrameOrientationTask: ``e = log3(R_FT)`` about F's axes, ``J_e = -Jlog3(R_TF) J_F[3:]``, drift, rows."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mbctl.control.exceptions import TaskSetupError
from mbctl.control.tasks import AccelerationGains, DynamicsState, FrameOrientationTask, KinematicState, Task
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

CASES = [(ARM, "tip"), (ARM, "elbow"), (FLOATING, "hand"), (FLOATING, "chest")]
IDS = [f"{model.name}-{frame}" for model, frame in CASES]
SEEDS = st.integers(min_value=0, max_value=2**32 - 1)


def _target_rotated_by(state: KinematicState, frame: str, theta_F: np.ndarray) -> pin.SE3:
    """``X_WT`` with ``R_WT = R_WF exp3(theta_F)`` (so ``R_FT = exp3(theta_F)``) and any position."""
    X_WF = state.frame_pose(state.frame_id(frame))
    return pin.SE3(X_WF.rotation @ pin.exp3(theta_F), X_WF.translation + 1.0)


@pytest.mark.parametrize(("model", "frame"), CASES, ids=IDS)
def test_the_error_is_the_rotation_vector_from_the_frame_to_the_target(model, frame):
    state = KinematicState(model, random_q(model, np.random.default_rng(1)))
    task = FrameOrientationTask(frame, model)
    with pytest.raises(TaskSetupError, match="no target set"):
        task.compute_error(state)
    task.set_target_from_state(state)
    np.testing.assert_allclose(task.compute_error(state), np.zeros(3), atol=1e-15)
    theta_F = np.array([0.3, -0.5, 0.8])  # |theta| < pi: log3 gives it back
    task.set_target(_target_rotated_by(state, frame, theta_F))  # the target's position is ignored
    np.testing.assert_allclose(task.compute_error(state), theta_F, atol=1e-14)
    assert task.residual(state).orientation_rad == pytest.approx(np.linalg.norm(theta_F), abs=1e-14)
    assert task.residual(state).position_m is None


@pytest.mark.parametrize(("model", "frame"), CASES, ids=IDS)
@settings(deadline=None, max_examples=15)
@given(seed=SEEDS)
def test_the_jacobian_matches_finite_differences_on_the_manifold(model, frame, seed):
    rng = np.random.default_rng(seed)
    q = random_q(model, rng, 1.0)
    state = KinematicState(model, q)
    task = FrameOrientationTask(frame, model)
    task.set_target(_target_rotated_by(state, frame, rng.uniform(-0.6, 0.6, 3)))
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
    task = FrameOrientationTask(frame, model)
    J, drift = task.jacobian_and_drift(DynamicsState(model, q, v))
    fd = fd_drift(task, model, q, v)
    err = inf_norm(drift - fd)
    assert err < 1e-7 * max(1.0, inf_norm(fd)), f"|Jdot v - fd|_inf = {err:.2e}"


@pytest.mark.parametrize(("model", "frame"), CASES, ids=IDS)
def test_at_the_target_the_acceleration_jacobian_is_minus_the_error_jacobian(model, frame):
    # e decreases as F turns towards T: de/dt = -w_F there, so e'' = -J vdot and a_des = kp e servoes
    state = KinematicState(model, random_q(model, np.random.default_rng(2)))
    task = FrameOrientationTask(frame, model)
    task.set_target_from_state(state)
    J_a, _ = task.jacobian_and_drift(DynamicsState(model, state.q))
    np.testing.assert_allclose(task.compute_jacobian(state), -J_a, atol=1e-14)


@pytest.mark.parametrize(("model", "frame"), CASES, ids=IDS)
def test_the_rows_and_the_stacked_objective_follow_the_error_and_jacobian(model, frame):
    rng = np.random.default_rng(5)
    q, v = random_q(model, rng), rng.standard_normal(model.nv)
    task = FrameOrientationTask(frame, model, cost=[0.0, 1.5, 3.0], gain=0.6, lm_damping=0.2,
                                servo=AccelerationGains(5.0, 0.9))
    state = KinematicState(model, q)
    task.set_target(_target_rotated_by(state, frame, rng.uniform(-0.5, 0.5, 3)))
    # velocity level: the active rows (about y and z), unweighted and both negated
    e, J = task.error_and_jacobian(state)
    assert task.active_rows().tolist() == [1, 2]
    J_rows, e_rows = velocity_rows(task, state)
    np.testing.assert_allclose(J_rows, -J[1:], atol=1e-14)
    np.testing.assert_allclose(e_rows, -e[1:], atol=1e-15)
    task.set_cost(1.0)  # all rows active: the other branch of write_velocity_rows
    J_rows, e_rows = velocity_rows(task, state)
    np.testing.assert_allclose(J_rows, -J, atol=1e-14)
    np.testing.assert_allclose(e_rows, -e, atol=1e-15)
    task.set_cost([0.0, 1.5, 3.0])
    H, c, mu = velocity_objective(task, state)
    H_ref, c_ref, mu_ref = expected_velocity_objective(task, e, J)
    np.testing.assert_allclose(H, H_ref, atol=1e-13)
    np.testing.assert_allclose(c, c_ref, atol=1e-13)
    assert mu == pytest.approx(mu_ref, rel=1e-13)
    # acceleration level: J = J_F[3:] (LOCAL), a_des = kp e - kd J v in F
    dyn = DynamicsState(model, q, v)
    J_a, drift = task.jacobian_and_drift(dyn)
    np.testing.assert_allclose(J_a, dyn.frame_jacobian(task.frame_id, pin.LOCAL)[3:], atol=1e-15)
    a_des = 25.0 * e - 2 * 0.9 * 5.0 * (J_a @ v)
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


def test_the_rows_need_a_target():
    state = DynamicsState(ARM)
    task = FrameOrientationTask("tip", ARM)
    with pytest.raises(TaskSetupError, match="tip orientation: no target set"):
        acceleration_rows(task, state)
    with pytest.raises(TaskSetupError, match="no target set"):
        velocity_rows(task, KinematicState(ARM))
