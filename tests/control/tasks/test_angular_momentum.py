"""AngularMomentumTask: ``J = A_g[3:]`` (``h = J v``, the angular momentum about the CoM), drift
``dA_g[3:] v``, ``a_des = -kd h``. Acceleration level only: it has no configuration error to
differentiate, so ``J`` is checked against the momentum summed body by body instead."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mbctl.control.exceptions import TaskSetupError
from mbctl.control.tasks import AccelerationGains, AngularMomentumTask, DynamicsState, KinematicState, Task
from tests.control.tasks.conftest import (
    FLOATING,
    MODELS,
    acceleration_objective,
    acceleration_rows,
    expected_acceleration_objective,
    fd_drift,
    inf_norm,
    random_q,
    velocity_objective,
)

IDS = [model.name for model in MODELS]
SEEDS = st.integers(min_value=0, max_value=2**32 - 1)


def _momentum_by_hand(model: pin.Model, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(p_W, h_G)``: linear momentum [kg m/s] and angular momentum about the CoM [kg m^2/s], in W.

    Each body's momentum ``Y_i v_i`` in its joint frame is moved to the world origin O and summed;
    then ``h_G = h_O - p_WC x p_W``.
    """
    data = model.createData()
    pin.forwardKinematics(model, data, q, v)
    total = pin.Force.Zero()
    for j in range(1, model.njoints):
        total += data.oMi[j].act(model.inertias[j] * data.v[j])
    p_WC = pin.centerOfMass(model, data, q)
    return total.linear, total.angular - np.cross(p_WC, total.linear)


@pytest.mark.parametrize("model", MODELS, ids=IDS)
def test_j_v_is_the_angular_momentum_about_the_centre_of_mass(model):
    rng = np.random.default_rng(11)
    q, v = random_q(model, rng, 1.0), rng.standard_normal(model.nv)
    state = DynamicsState(model, q, v)
    J, _ = AngularMomentumTask().jacobian_and_drift(state)
    assert J.shape == (3, model.nv)
    p_W, h_G = _momentum_by_hand(model, q, v)
    np.testing.assert_allclose(J @ v, h_G, atol=1e-12)
    np.testing.assert_allclose(state.angular_momentum(), h_G, atol=1e-12)
    np.testing.assert_allclose(state.centroidal_map()[:3] @ v, p_W, atol=1e-12)  # the linear rows: m v_C


def test_a_floating_robot_spinning_rigidly_about_its_com_has_h_equal_to_its_inertia_times_w():
    # at the neutral pose B = W; joints still, the base twist that keeps the CoM in place
    q = pin.neutral(FLOATING)
    data = FLOATING.createData()
    pin.forwardKinematics(FLOATING, data, q)
    composite = pin.Inertia.Zero()
    for j in range(1, FLOATING.njoints):
        composite += data.oMi[j].act(FLOATING.inertias[j])
    w_W = np.array([0.3, -0.2, 0.5])
    v = np.zeros(FLOATING.nv)
    v[:3], v[3:6] = np.cross(composite.lever, w_W), w_W  # v_O = w x (O - C)
    state = DynamicsState(FLOATING, q, v)
    np.testing.assert_allclose(state.angular_momentum(), composite.inertia @ w_W, atol=1e-13)
    np.testing.assert_allclose(state.centroidal_map()[:3] @ v, np.zeros(3), atol=1e-13)


@pytest.mark.parametrize("model", MODELS, ids=IDS)
@settings(deadline=None, max_examples=15)
@given(seed=SEEDS, centroidal_first=st.booleans())
def test_the_drift_is_the_time_derivative_of_the_jacobian_along_v(model, seed, centroidal_first):
    # free-flyer root: dA_g v from the root's bias wrench; fixed base: Pinocchio's pass
    rng = np.random.default_rng(seed)
    q, v = random_q(model, rng, 1.0), rng.standard_normal(model.nv)
    state = DynamicsState(model, q, v)
    if centroidal_first:
        state.com_drift()  # the CoM's shortcut first must not change the cached centroidal drift
    task = AngularMomentumTask()
    _, drift = task.jacobian_and_drift(state)
    fd = fd_drift(task, model, q, v)
    err = inf_norm(drift - fd)
    assert err < 1e-7 * max(1.0, inf_norm(fd)), f"|dA_g v - fd|_inf = {err:.2e}"


@pytest.mark.parametrize("model", MODELS, ids=IDS)
def test_the_rows_and_the_stacked_objective_damp_the_momentum(model):
    rng = np.random.default_rng(12)
    q, v = random_q(model, rng), rng.standard_normal(model.nv)
    task = AngularMomentumTask(cost=[0.5, 2.0, 1.0], servo=AccelerationGains(4.0, 0.75))
    dyn = DynamicsState(model, q, v)
    J, drift = task.jacobian_and_drift(dyn)
    a_des = -2 * 0.75 * 4.0 * (J @ v)  # -kd h; kp unused
    np.testing.assert_allclose(task.desired_acceleration(dyn, J), a_des, atol=1e-12)
    W_a, r_a = acceleration_rows(task, dyn)  # the fast path
    np.testing.assert_allclose(W_a, task.cost[:, None] * J, atol=1e-15)
    np.testing.assert_allclose(r_a, task.cost * (a_des - drift), atol=1e-12)
    W_g, r_g = np.zeros((3, model.nv)), np.zeros(3)
    Task.write_acceleration_rows(task, dyn, W_g, r_g)
    np.testing.assert_allclose(r_a, r_g, atol=1e-12)
    H, c = acceleration_objective(task, dyn)
    H_ref, c_ref = expected_acceleration_objective(task, J, drift, a_des)
    np.testing.assert_allclose(H, H_ref, atol=1e-12)
    np.testing.assert_allclose(c, c_ref, atol=1e-10)
    assert task.residual(dyn).regularising


def test_it_has_no_velocity_level_form():
    state = KinematicState(FLOATING)
    task = AngularMomentumTask()
    for call in (task.compute_error, task.compute_jacobian):
        with pytest.raises(TaskSetupError, match="angular momentum: .* has no velocity-level"):
            call(state)
    with pytest.raises(TaskSetupError, match="no velocity-level"):
        velocity_objective(task, state)
