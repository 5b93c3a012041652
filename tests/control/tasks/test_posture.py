"""PostureTask: ``e = q ⊖ q_target`` (free flyer zeroed), ``J_e`` (identity or ``dDifference``), its rows.

The arm and the hinge-only floating model take the stack's diagonal shortcut (``is_diagonal``);
the floating model with a ball shoulder stacks dense rows.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mbctl.control.exceptions import TaskSetupError
from mbctl.control.tasks import AccelerationGains, DynamicsState, KinematicState, PostureTask
from tests.control.tasks.conftest import (
    ARM,
    FLOATING,
    FLOATING_HINGES,
    MODELS,
    acceleration_objective,
    acceleration_rows,
    expected_acceleration_objective,
    expected_velocity_objective,
    fd_drift,
    fd_jacobian,
    inf_norm,
    joint_mask,
    kinematic_error,
    random_q,
    velocity_objective,
)

IDS = [model.name for model in MODELS]
SEEDS = st.integers(min_value=0, max_value=2**32 - 1)


def test_the_diagonal_shortcut_is_taken_for_one_dof_joints_only():
    assert PostureTask(ARM).is_diagonal and PostureTask(FLOATING_HINGES).is_diagonal
    assert not PostureTask(FLOATING).is_diagonal  # the ball joint's block is dDifference
    np.testing.assert_array_equal(PostureTask(FLOATING).mask, joint_mask(FLOATING))


@pytest.mark.parametrize("model", MODELS, ids=IDS)
def test_the_error_is_the_configuration_difference_without_the_free_flyer(model):
    rng = np.random.default_rng(5)
    q = random_q(model, rng)
    state = KinematicState(model, q)
    task = PostureTask(model)
    with pytest.raises(TaskSetupError, match="posture: no target set"):
        task.compute_error(state)
    task.set_target_from_state(state)
    np.testing.assert_allclose(task.compute_error(state), np.zeros(model.nv), atol=1e-15)
    # q_target = q ⊕ (-d): q ⊖ q_target = d on every joint kind (ball included), the base's zeroed
    d = 0.4 * rng.standard_normal(model.nv)
    task.set_target(pin.integrate(model, q, -d))
    np.testing.assert_allclose(task.compute_error(state), d * joint_mask(model), atol=1e-14)
    np.testing.assert_allclose(task.masked_error(state), d, atol=1e-14)  # the base's kept there
    assert task.residual(state).deviation == pytest.approx(np.linalg.norm(d * joint_mask(model)), rel=1e-13)
    assert task.residual(state).regularising


@pytest.mark.parametrize("model", MODELS, ids=IDS)
@settings(deadline=None, max_examples=15)
@given(seed=SEEDS)
def test_the_jacobian_matches_finite_differences_on_the_manifold(model, seed):
    rng = np.random.default_rng(seed)
    q = random_q(model, rng, 1.0)
    task = PostureTask(model)
    task.set_target(pin.integrate(model, q, rng.uniform(-0.8, 0.8, model.nv)))  # within 1.4 rad
    state = KinematicState(model, q)
    J = task.compute_jacobian(state)
    assert J.shape == (model.nv, model.nv)
    err = inf_norm(J - fd_jacobian(kinematic_error(task, model), model, q))
    assert err < 1e-8, f"|J - J_fd|_inf = {err:.2e}"
    if task.is_diagonal:
        np.testing.assert_array_equal(J, np.diag(joint_mask(model)))


@pytest.mark.parametrize("model", MODELS, ids=IDS)
def test_the_acceleration_rows_are_the_joint_dofs_with_no_drift(model):
    rng = np.random.default_rng(6)
    q, v = random_q(model, rng), rng.standard_normal(model.nv)
    task = PostureTask(model, cost=rng.uniform(0.5, 2.0, model.nv), servo=AccelerationGains(3.0, 0.5))
    task.set_target(random_q(model, rng))
    dyn = DynamicsState(model, q, v)
    J, drift = task.jacobian_and_drift(dyn)
    mask = joint_mask(model)
    np.testing.assert_array_equal(J, np.diag(mask))  # diag(mask) even with a ball joint (documented)
    np.testing.assert_array_equal(drift, np.zeros(model.nv))
    np.testing.assert_array_equal(fd_drift(task, model, q, v), np.zeros(model.nv))
    # a_des = -kp e - kd v on the joint dofs, 0 on the free flyer's
    e = task.compute_error(dyn)
    a_des = (-9.0 * e - 2 * 0.5 * 3.0 * v) * mask
    np.testing.assert_allclose(task.desired_acceleration(dyn, J), a_des, atol=1e-13)
    np.testing.assert_allclose(task.masked_desired_acceleration(dyn) * mask, a_des, atol=1e-13)
    W_a, r_a = acceleration_rows(task, dyn)
    np.testing.assert_allclose(W_a, task.cost[:, None] * J, atol=1e-15)
    np.testing.assert_allclose(r_a, task.cost * a_des, atol=1e-13)
    # the stack: the diagonal shortcut (or dense rows, with a ball joint) gives the same H and c
    H_a, c_a = acceleration_objective(task, dyn)
    H_ref, c_ref = expected_acceleration_objective(task, J, drift, a_des)
    np.testing.assert_allclose(H_a, H_ref, atol=1e-13)
    np.testing.assert_allclose(c_a, c_ref, atol=1e-12)


@pytest.mark.parametrize("model", MODELS, ids=IDS)
def test_the_stacked_velocity_objective_follows_the_error_and_jacobian(model):
    rng = np.random.default_rng(7)
    q = random_q(model, rng)
    task = PostureTask(model, cost=rng.uniform(0.5, 2.0, model.nv), gain=0.6)
    task.set_target(random_q(model, rng))
    state = KinematicState(model, q)
    e, J = task.error_and_jacobian(state)
    H, c, mu = velocity_objective(task, state)
    H_ref, c_ref, _ = expected_velocity_objective(task, e, J)
    np.testing.assert_allclose(H, H_ref, atol=1e-13)
    np.testing.assert_allclose(c, c_ref, atol=1e-13)
    assert mu == 0.0  # no LM damping asked
    np.testing.assert_allclose(task.cost2_mask(), task.cost**2 * joint_mask(model), atol=1e-15)


@pytest.mark.parametrize("model", [ARM, FLOATING, FLOATING_HINGES], ids=IDS)
def test_the_lm_term_is_lm_damping_times_the_squared_rows(model):
    rng = np.random.default_rng(8)
    q = random_q(model, rng)
    task = PostureTask(model, cost=rng.uniform(0.5, 2.0, model.nv), gain=0.8, lm_damping=0.3)
    task.set_target(random_q(model, rng))  # the target's base pose differs from q's
    state = KinematicState(model, q)
    e, J = task.error_and_jacobian(state)
    _, _, mu = velocity_objective(task, state)
    _, _, mu_ref = expected_velocity_objective(task, e, J)
    assert mu_ref > 0.0
    assert mu == pytest.approx(mu_ref, rel=1e-12)


def test_a_bad_target_is_named():
    with pytest.raises(TaskSetupError, match=r"posture: target must be a finite \(14,\) configuration"):
        PostureTask(FLOATING).set_target(np.zeros(13))


def _floating_unbounded_hinge() -> pin.Model:
    """A free flyer and an unbounded hinge (nq 2, nv 1: its q ⊖ q_target is no difference of coordinates)."""
    model = pin.Model()
    root = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "root")
    model.appendBodyToJoint(root, pin.Inertia.FromBox(2.0, 0.2, 0.2, 0.2), pin.SE3.Identity())
    hinge = model.addJoint(root, pin.JointModelRUBY(), pin.SE3(np.eye(3), np.array([0.0, 0.1, 0.0])), "hinge")
    model.appendBodyToJoint(hinge, pin.Inertia.FromBox(1.0, 0.1, 0.1, 0.3), pin.SE3.Identity())
    return model


@pytest.mark.parametrize("model", [FLOATING_HINGES, _floating_unbounded_hinge()], ids=["hinges", "unbounded"])
def test_the_acceleration_term_equals_the_diagonal_tasks_generic_one(model):
    """PostureTask's c term (kp cost^2 e + kd cost^2 v, products cached; with coordinate joints one
    linear map of [q; v]) against DiagonalTask's (cost^2 mask times -a_des), also after the cost, the
    gains and the target change."""
    from mbctl.control.tasks.diagonal import DiagonalTask

    rng = np.random.default_rng(23)
    task = PostureTask(model, rng.uniform(0.01, 0.2, model.nv), servo=AccelerationGains(6.0, 0.8))
    assert task.is_diagonal and (task._coordinates is None) == (model is not FLOATING_HINGES)  # both paths
    with pytest.raises(TaskSetupError, match="no target"):
        task.add_acceleration_term(DynamicsState(model), np.zeros(model.nv), np.zeros(model.nv))
    task.set_target(random_q(model, rng))
    for k in range(4):
        if k == 1:
            task.set_cost(0.3)
        if k == 2:
            task.servo = AccelerationGains(2.0, 1.5)
        if k == 3:
            task.set_target(random_q(model, rng))
        state = DynamicsState(model, random_q(model, rng), rng.standard_normal(model.nv))
        c0 = rng.standard_normal(model.nv)
        c_fast, c_generic, tmp = c0.copy(), c0.copy(), np.zeros(model.nv)
        task.add_acceleration_term(state, c_fast, tmp)
        DiagonalTask.add_acceleration_term(task, state, c_generic, tmp)
        np.testing.assert_allclose(c_fast, c_generic, rtol=1e-14, atol=1e-14)
        assert np.abs(c_fast - c0).max() > 1e-2
