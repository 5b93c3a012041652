"""DampingTask: ``e = 0``, ``J = diag(mask)``, gain 0: ``cost^2`` on H's joint diagonal, nothing in c.

Its Jacobian is a regulariser's, not ``de/dq`` (the error is identically zero), so there is no
finite-difference check; there is no acceleration-level form either.
"""

from __future__ import annotations

import numpy as np
import pytest

from mbctl.control.exceptions import TaskSetupError
from mbctl.control.tasks import DampingTask, DynamicsState, KinematicState, Task
from tests.control.tasks.conftest import (
    FLOATING,
    MODELS,
    acceleration_objective,
    expected_velocity_objective,
    joint_mask,
    random_q,
    velocity_objective,
)

IDS = [model.name for model in MODELS]


@pytest.mark.parametrize("model", MODELS, ids=IDS)
def test_the_error_is_zero_and_the_jacobian_the_joint_identity(model):
    state = KinematicState(model, random_q(model, np.random.default_rng(9)))
    task = DampingTask(model, cost=0.1)
    mask = joint_mask(model)  # zero on the floating models' free flyer
    np.testing.assert_array_equal(task.compute_error(state), np.zeros(model.nv))
    np.testing.assert_array_equal(task.compute_jacobian(state), np.diag(mask))
    np.testing.assert_array_equal(task.mask, mask)
    assert task.gain == 0.0 and task.regularizing and task.is_diagonal
    assert task.residual(state).deviation == 0.0 and task.residual(state).regularising


@pytest.mark.parametrize("model", MODELS, ids=IDS)
def test_the_stack_adds_cost_squared_on_the_joint_diagonal_and_nothing_else(model):
    rng = np.random.default_rng(10)
    cost = rng.uniform(0.01, 0.1, model.nv)
    task = DampingTask(model, cost)
    state = KinematicState(model, random_q(model, rng))
    H, c, mu = velocity_objective(task, state)
    np.testing.assert_array_equal(H, np.diag(cost**2 * task.mask))
    np.testing.assert_array_equal(c, np.zeros(model.nv))
    assert mu == 0.0
    e, J = task.compute_error(state), task.compute_jacobian(state)
    H_ref, c_ref, _ = expected_velocity_objective(task, e, J)
    np.testing.assert_allclose(H, H_ref, atol=1e-15)
    np.testing.assert_allclose(c, c_ref, atol=1e-15)
    # its generic dense rows are the same objective: W = diag(cost mask), r = 0
    W_t, r_t = np.zeros((model.nv, model.nv)), np.zeros(model.nv)
    assert Task.write_qp_rows(task, state, W_t, r_t) == 0.0
    np.testing.assert_allclose(W_t.T @ W_t, H, atol=1e-15)
    np.testing.assert_array_equal(r_t, np.zeros(model.nv))


def test_it_has_no_acceleration_level_form():
    state = DynamicsState(FLOATING)
    task = DampingTask(FLOATING)
    with pytest.raises(TaskSetupError, match="damping: DampingTask has no acceleration-level form"):
        task.jacobian_and_drift(state)
    with pytest.raises(TaskSetupError, match="no acceleration-level form"):
        acceleration_objective(task, state)


def test_a_misshaped_cost_is_named():
    with pytest.raises(TaskSetupError, match=r"damping cost must be .* a vector of shape \(12,\)"):
        DampingTask(FLOATING, cost=np.ones(3))
