"""TaskStack at the velocity level: a mixed stack is the sum of its tasks' objectives, and it
re-reads weights changed between solves (the acceleration-level mixed stack is in
tests/control/wbc/test_wbc.py)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from mbctl.control.tasks import (
    ComTask,
    DampingTask,
    FramePoseTask,
    KinematicState,
    PostureTask,
    RelativeFrameTask,
    TaskStack,
)
from tests.control.tasks.conftest import FLOATING_HINGES, expected_velocity_objective, random_q

MODEL = FLOATING_HINGES


def _tasks(state: KinematicState, rng: np.random.Generator) -> list:
    pose = FramePoseTask("hand", MODEL, [1.0, 0.0, 2.0], 0.5, gain=0.8, lm_damping=0.2)
    X_WH = state.frame_pose(state.frame_id("hand"))
    pose.set_target(X_WH * pin.exp6(pin.Motion(0.2 * rng.standard_normal(6))))
    com = ComTask([1.0, 1.0, 0.0], gain=0.5, lm_damping=1.0)
    com.set_target(state.com() + 0.05 * rng.standard_normal(3))
    relative = RelativeFrameTask("foot", "chest", MODEL, 1.0, 0.0, gain=0.3)
    relative.set_target(pin.exp6(pin.Motion(0.2 * rng.standard_normal(6))) * _relative_pose(state))
    posture = PostureTask(MODEL, rng.uniform(0.01, 0.1, MODEL.nv), gain=0.9, lm_damping=0.5)
    posture.set_target(random_q(MODEL, rng))
    return [pose, com, relative, posture, DampingTask(MODEL, 1e-2)]


def _relative_pose(state: KinematicState) -> pin.SE3:
    return state.frame_pose(state.frame_id("chest")).actInv(state.frame_pose(state.frame_id("foot")))


def _expected(tasks, state):
    H, c, mu = np.zeros((MODEL.nv, MODEL.nv)), np.zeros(MODEL.nv), 0.0
    for task in tasks:
        e, J = task.error_and_jacobian(state)
        H_t, c_t, mu_t = expected_velocity_objective(task, e, J)
        H, c, mu = H + H_t, c + c_t, mu + mu_t
    return H, c, mu


def _objective(stack, state):
    H, c = np.full((MODEL.nv, MODEL.nv), np.nan), np.full(MODEL.nv, np.nan)
    mu = stack.velocity_objective(state, H, c)
    return H, c, mu


def test_a_mixed_stack_is_the_sum_of_its_tasks_objectives():
    rng = np.random.default_rng(14)
    state = KinematicState(MODEL, random_q(MODEL, rng))
    tasks = _tasks(state, rng)
    stack = TaskStack(MODEL.nv, tasks)
    H, c, mu = _objective(stack, state)
    H_ref, c_ref, mu_ref = _expected(tasks, state)
    np.testing.assert_allclose(H, H_ref, atol=1e-12)
    np.testing.assert_allclose(c, c_ref, atol=1e-12)
    assert mu == pytest.approx(mu_ref, rel=1e-12)
    # the dense rows: the active rows of pose (5), CoM (2) and relative (3), weighted
    W, r = stack.velocity_rows()
    assert W.shape == (10, MODEL.nv) and r.shape == (10,)
    diagonal = np.diag(tasks[3].cost2_mask() + tasks[4].cost2_mask())  # posture and damping
    np.testing.assert_allclose(W.T @ W + diagonal, H, atol=1e-12)


def test_weights_changed_between_solves_are_read_again():
    rng = np.random.default_rng(15)
    state = KinematicState(MODEL, random_q(MODEL, rng))
    tasks = _tasks(state, rng)
    stack = TaskStack(MODEL.nv, tasks)
    _objective(stack, state)
    tasks[0].set_cost([1.0, 1.0, 1.0, 0.0, 0.0, 3.0])  # other active rows
    tasks[1].gain = 0.1
    tasks[2].lm_damping = 0.7
    tasks[3].set_cost(0.2)
    tasks[4].set_cost(0.0)  # no damping at all
    H, c, mu = _objective(stack, state)
    H_ref, c_ref, mu_ref = _expected(tasks, state)
    np.testing.assert_allclose(H, H_ref, atol=1e-12)
    np.testing.assert_allclose(c, c_ref, atol=1e-12)
    assert mu == pytest.approx(mu_ref, rel=1e-12)
    assert stack.velocity_rows()[0].shape == (4 + 2 + 3, MODEL.nv)  # pose, CoM, relative
