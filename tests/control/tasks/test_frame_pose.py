"""FramePoseTask: ``e = log6(X_FT)`` in F, ``J_e = -Jlog6(X_TF) J_F``, the spatial drift, its rows."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mbctl.control.exceptions import TaskSetupError
from mbctl.control.tasks import AccelerationGains, DynamicsState, FramePoseTask, KinematicState
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


def _target_moved_by(state: KinematicState, frame: str, xi_F: np.ndarray) -> pin.SE3:
    """``X_WT = X_WF exp6(xi_F)``, so ``X_FT = exp6(xi_F)`` (xi = [v; w] in F)."""
    return state.frame_pose(state.frame_id(frame)) * pin.exp6(pin.Motion(xi_F))


@pytest.mark.parametrize(("model", "frame"), CASES, ids=IDS)
def test_the_error_is_the_twist_from_the_frame_to_the_target(model, frame):
    state = KinematicState(model, random_q(model, np.random.default_rng(2)))
    task = FramePoseTask(frame, model)
    with pytest.raises(TaskSetupError, match="no target set"):
        task.compute_error(state)
    task.set_target_from_state(state)
    np.testing.assert_allclose(task.compute_error(state), np.zeros(6), atol=1e-15)
    xi_F = np.array([0.1, -0.05, 0.2, 0.4, -0.3, 0.6])  # rotation below pi: log6 gives it back
    task.set_target(_target_moved_by(state, frame, xi_F))
    np.testing.assert_allclose(task.compute_error(state), xi_F, atol=1e-14)
    # a pure translation t_F: the error is t_F itself
    task.set_target(_target_moved_by(state, frame, np.r_[0.1, 0.2, -0.3, 0.0, 0.0, 0.0]))
    np.testing.assert_allclose(task.compute_error(state), [0.1, 0.2, -0.3, 0, 0, 0], atol=1e-15)
    residual = task.residual(state)
    assert residual.position_m == pytest.approx(np.sqrt(0.14), abs=1e-14)
    assert residual.orientation_rad == pytest.approx(0.0, abs=1e-14)


@pytest.mark.parametrize(("model", "frame"), CASES, ids=IDS)
@settings(deadline=None, max_examples=15)
@given(seed=SEEDS, pure_translation=st.booleans())
def test_the_jacobian_matches_finite_differences_on_the_manifold(model, frame, seed, pure_translation):
    # a pure translation error (zero relative rotation, the palm-target case) keeps Jlog6's coupling
    rng = np.random.default_rng(seed)
    q = random_q(model, rng, 1.0)
    state = KinematicState(model, q)
    xi_F = rng.uniform(-0.5, 0.5, 6)
    if pure_translation:
        xi_F[3:] = 0.0
    task = FramePoseTask(frame, model)
    task.set_target(_target_moved_by(state, frame, xi_F))
    e, J = task.error_and_jacobian(state)
    assert J.shape == (6, model.nv)
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
    task = FramePoseTask(frame, model)
    _, drift = task.jacobian_and_drift(DynamicsState(model, q, v))
    fd = fd_drift(task, model, q, v)
    err = inf_norm(drift - fd)
    assert err < 1e-7 * max(1.0, inf_norm(fd)), f"|Jdot v - fd|_inf = {err:.2e}"


@pytest.mark.parametrize(("model", "frame"), CASES, ids=IDS)
def test_at_the_target_the_acceleration_jacobian_is_minus_the_error_jacobian(model, frame):
    state = KinematicState(model, random_q(model, np.random.default_rng(3)))
    task = FramePoseTask(frame, model)
    task.set_target_from_state(state)
    J_a, _ = task.jacobian_and_drift(DynamicsState(model, state.q))
    np.testing.assert_allclose(task.compute_jacobian(state), -J_a, atol=1e-14)


@pytest.mark.parametrize(("model", "frame"), CASES, ids=IDS)
def test_the_rows_and_the_stacked_objective_follow_the_error_and_jacobian(model, frame):
    rng = np.random.default_rng(6)
    q, v = random_q(model, rng), rng.standard_normal(model.nv)
    task = FramePoseTask(frame, model, position_cost=[1.0, 2.0, 0.5], orientation_cost=[0.3, 0.0, 1.0],
                         gain=0.8, lm_damping=0.4, servo=AccelerationGains(6.0, 0.7))
    assert task.cost.tolist() == [1.0, 2.0, 0.5, 0.3, 0.0, 1.0]  # (position, orientation)
    state = KinematicState(model, q)
    task.set_target(_target_moved_by(state, frame, rng.uniform(-0.3, 0.3, 6)),
                    v=rng.standard_normal(3), a=rng.standard_normal(3))
    e, J = task.error_and_jacobian(state)
    # velocity level: the active rows, unweighted and both negated
    active = [0, 1, 2, 3, 5]
    assert task.active_rows().tolist() == active
    J_rows, e_rows = velocity_rows(task, state)
    np.testing.assert_allclose(J_rows, -J[active], atol=1e-14)
    np.testing.assert_allclose(e_rows, -e[active], atol=1e-15)
    W_t, r_t = np.zeros((6, model.nv)), np.zeros(6)
    mu = task.write_qp_rows(state, W_t, r_t)  # the fast path
    np.testing.assert_allclose(W_t, task.cost[:, None] * J, atol=1e-14)
    np.testing.assert_allclose(r_t, -0.8 * task.cost * e, atol=1e-15)
    H, c, mu_stack = velocity_objective(task, state)
    H_ref, c_ref, mu_ref = expected_velocity_objective(task, e, J)
    np.testing.assert_allclose(H, H_ref, atol=1e-13)
    np.testing.assert_allclose(c, c_ref, atol=1e-13)
    assert mu == pytest.approx(mu_ref, rel=1e-13) and mu_stack == pytest.approx(mu_ref, rel=1e-13)
    # acceleration level: J_F (LOCAL), a_des = a_ref + kp e + kd (v_ref - J v), references rotated into F
    dyn = DynamicsState(model, q, v)
    J_a, drift = task.jacobian_and_drift(dyn)
    np.testing.assert_allclose(J_a, dyn.frame_jacobian(task.frame_id, pin.LOCAL), atol=1e-15)
    R_FW = dyn.frame_pose(task.frame_id).rotation.T
    v_ref, a_ref = np.r_[R_FW @ task.v_ref_W, 0, 0, 0], np.r_[R_FW @ task.a_ref_W, 0, 0, 0]
    a_des = a_ref + 36.0 * e + 2 * 0.7 * 6.0 * (v_ref - J_a @ v)
    np.testing.assert_allclose(task.desired_acceleration(dyn, J_a), a_des, atol=1e-12)
    W_a, r_a = acceleration_rows(task, dyn)
    np.testing.assert_allclose(W_a, task.cost[:, None] * J_a, atol=1e-15)
    np.testing.assert_allclose(r_a, task.cost * (a_des - drift), atol=1e-12)
    H_a, c_a = acceleration_objective(task, dyn)
    H_ref, c_ref = expected_acceleration_objective(task, J_a, drift, a_des)
    np.testing.assert_allclose(H_a, H_ref, atol=1e-12)
    np.testing.assert_allclose(c_a, c_ref, atol=1e-10)


def test_a_position_only_task_writes_three_rows_and_reports_no_angle():
    rng = np.random.default_rng(7)
    state = KinematicState(FLOATING, random_q(FLOATING, rng))
    task = FramePoseTask("hand", FLOATING, position_cost=1.0, orientation_cost=0.0)
    task.set_target(_target_moved_by(state, "hand", rng.uniform(-0.3, 0.3, 6)))
    e, J = task.error_and_jacobian(state)
    J_rows, e_rows = velocity_rows(task, state)
    np.testing.assert_allclose(J_rows, -J[:3], atol=1e-14)
    np.testing.assert_allclose(e_rows, -e[:3], atol=1e-15)
    residual = task.residual(state)
    assert residual.orientation_rad is None
    X_TF = task.transform_target_to_world.actInv(state.frame_pose(task.frame_id))
    assert residual.position_m == pytest.approx(np.linalg.norm(X_TF.translation), rel=1e-14)


def test_bad_costs_are_named():
    with pytest.raises(TaskSetupError, match="tip orientation_cost must be a non-negative"):
        FramePoseTask("tip", ARM, orientation_cost=[1.0, -1.0, 1.0])
    with pytest.raises(TaskSetupError, match="tip position_cost must be a non-negative"):
        FramePoseTask("tip", ARM, position_cost=[1.0, 1.0])
    with pytest.raises(TaskSetupError, match=r"gain must be in \[0, 1\]"):
        FramePoseTask("tip", ARM, gain=1.5)


@pytest.mark.parametrize(("model", "frame"), CASES, ids=IDS)
def test_angular_references_are_fed_forward_in_the_stacked_terms_and_the_whole_rows(model, frame):
    rng = np.random.default_rng(21)
    q, v = random_q(model, rng), rng.standard_normal(model.nv)
    task = FramePoseTask(frame, model, 2.0, 0.7, servo=AccelerationGains(5.0, 0.8))
    dyn = DynamicsState(model, q, v)
    v_W, a_W, w_W, alpha_W = (rng.standard_normal(3) for _ in range(4))
    task.set_target(_target_moved_by(dyn, frame, rng.uniform(-0.3, 0.3, 6)), v=v_W, a=a_W)
    task.set_angular_reference(w_W, alpha_W)
    np.testing.assert_array_equal(task.w_ref_W, w_W)
    np.testing.assert_array_equal(task.alpha_ref_W, alpha_W)
    J_a, drift = task.jacobian_and_drift(dyn)
    R_FW = dyn.frame_pose(task.frame_id).rotation.T
    kp, kd = 25.0, 2 * 0.8 * 5.0
    a_des = (np.r_[R_FW @ a_W, R_FW @ alpha_W] + kp * task.compute_error(dyn)
             + kd * (np.r_[R_FW @ v_W, R_FW @ w_W] - J_a @ v))
    np.testing.assert_allclose(task.desired_acceleration(dyn, J_a), a_des, atol=1e-12)
    J_t, r_t = np.full((6, model.nv), np.nan), np.full(6, np.nan)
    task.write_acceleration_terms(dyn, J_t, r_t)  # the stack's: a_des + kd J v - Jdot v
    np.testing.assert_array_equal(J_t, J_a)
    np.testing.assert_allclose(r_t, a_des + kd * J_a @ v - drift, atol=1e-12)
    H, c = acceleration_objective(task, dyn)
    H_ref, c_ref = expected_acceleration_objective(task, J_a, drift, a_des)
    np.testing.assert_allclose(H, H_ref, atol=1e-12)
    np.testing.assert_allclose(c, c_ref, atol=1e-10)
    with pytest.raises(TaskSetupError, match="target angular velocity"):
        task.set_angular_reference([0.0, np.nan, 0.0])
    task.set_target(task.transform_target_to_world)  # a new target: at rest in rotation
    assert not task.w_ref_W.any() and not task.alpha_ref_W.any()


def test_a_subclass_with_a_law_of_its_own_writes_its_rows_whole():
    class OwnLaw(FramePoseTask):
        def desired_acceleration(self, state, J):
            return np.full(6, 7.0)

    assert FramePoseTask.stacked_acceleration and not OwnLaw.stacked_acceleration
    rng = np.random.default_rng(22)
    dyn = DynamicsState(FLOATING, random_q(FLOATING, rng), rng.standard_normal(FLOATING.nv))
    task = OwnLaw("hand", FLOATING, 1.5, 0.5, servo=AccelerationGains(4.0, 1.0))
    task.set_target(dyn.frame_pose(task.frame_id))
    J_a, drift = task.jacobian_and_drift(dyn)
    H, c = acceleration_objective(task, dyn)  # its own a_des, not the pose law's
    H_ref, c_ref = expected_acceleration_objective(task, J_a, drift, np.full(6, 7.0))
    np.testing.assert_allclose(H, H_ref, atol=1e-12)
    np.testing.assert_allclose(c, c_ref, atol=1e-10)
