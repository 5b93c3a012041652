"""TaskStack: a mixed stack is the sum of its tasks' objectives at the velocity and acceleration levels,
and it re-reads weights changed between solves (another acceleration-level mixed stack is in
tests/control/wbc/test_wbc.py)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from mbctl.control.tasks import (
    AccelerationGains,
    AngularMomentumTask,
    ComTask,
    DampingTask,
    DynamicsState,
    FrameOrientationTask,
    FramePoseTask,
    KinematicState,
    PostureTask,
    RelativeFrameTask,
    Task,
    TaskStack,
)
from tests.control.tasks.conftest import ARM, FLOATING_HINGES, expected_velocity_objective, random_q

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


def _acceleration_tasks(state: DynamicsState, rng: np.random.Generator) -> list:
    """Stacked tasks (CoM, orientations on the root and on the arm, a moving pose) and tasks written whole."""
    com = ComTask([1.0, 2.0, 0.5], servo=AccelerationGains(7.0, 0.9))
    com.set_target(state.com() + 0.05 * rng.standard_normal(3), rng.standard_normal(3),
                   rng.standard_normal(3))
    tasks = [com]
    for frame, cost in (("chest", [1.0, 0.5, 2.0]), ("hand", 3.0)):
        task = FrameOrientationTask(frame, MODEL, cost, servo=AccelerationGains(5.0, 0.7))
        X_WF = state.frame_pose(state.frame_id(frame))
        task.set_target(X_WF * pin.exp6(pin.Motion(0.3 * rng.standard_normal(6))))
        tasks.append(task)
    pose = FramePoseTask("foot", MODEL, 2.0, 0.5, servo=AccelerationGains(6.0, 1.0))
    X_WF = state.frame_pose(state.frame_id("foot"))
    pose.set_target(X_WF * pin.exp6(pin.Motion(0.2 * rng.standard_normal(6))), rng.standard_normal(3),
                    rng.standard_normal(3))
    pose.set_angular_reference(rng.standard_normal(3), rng.standard_normal(3))
    posture = PostureTask(MODEL, rng.uniform(0.01, 0.1, MODEL.nv), servo=AccelerationGains(4.0, 1.0))
    posture.set_target(random_q(MODEL, rng))
    return [*tasks, pose, posture, AngularMomentumTask(0.3, servo=AccelerationGains(3.0, 1.0))]


def _generic_acceleration_objective(tasks, state, regularization):
    """``H = W^T W + diag``, ``c = -W^T r`` from every task's generic rows (Task.write_acceleration_rows)."""
    rows = [(np.zeros((t.k, MODEL.nv)), np.zeros(t.k)) for t in tasks]
    for task, (W_t, r_t) in zip(tasks, rows, strict=True):
        Task.write_acceleration_rows(task, state, W_t, r_t)
    W, r = np.vstack([w for w, _ in rows]), np.concatenate([r for _, r in rows])
    return W.T @ W + regularization * np.eye(MODEL.nv), -W.T @ r


def test_the_acceleration_stack_equals_every_task_written_whole():
    """The stacked tasks' terms, weighed and damped by the stack, give the generic rows' objective.

    The root frame's Jacobian is written once (constant) and its drift is zero: checked on other
    states than the first, and again after costs and gains change between solves.
    """
    rng = np.random.default_rng(16)
    stack, tasks = None, None
    for k in range(4):
        state = DynamicsState(MODEL, random_q(MODEL, rng), rng.standard_normal(MODEL.nv))
        if stack is None:
            tasks = _acceleration_tasks(state, rng)
            stack = TaskStack(MODEL.nv, tasks)
            assert [t.stacked_acceleration for t in tasks] == [True, True, True, True, False, False]
        if k == 2:
            tasks[0].set_cost(0.7)
            tasks[1].servo = AccelerationGains(9.0, 0.3)
            tasks[4].set_cost(0.2)
        # H in C order, a strided block (the fallback), in Fortran order (gemm writes H^T or H in place)
        H = np.full((MODEL.nv, MODEL.nv + 3 * (k % 2)), np.nan, order="F" if k == 2 else "C")[:, :MODEL.nv]
        c = np.full(MODEL.nv, np.nan)
        stack.acceleration_objective(state, H, c, 1e-4)
        H_ref, c_ref = _generic_acceleration_objective(tasks, state, 1e-4)
        np.testing.assert_allclose(H, H_ref, rtol=1e-13, atol=1e-12)
        np.testing.assert_allclose(c, c_ref, rtol=1e-13, atol=1e-11)
        assert np.abs(c).max() > 1.0  # a real test: the terms are not all zero


def test_stacked_rows_with_one_gain_are_damped_by_one_product():
    """Every dense row stacked with one kd (and a posture): kd W v by one BLAS call, one objective."""
    rng = np.random.default_rng(17)
    state = DynamicsState(MODEL, random_q(MODEL, rng), rng.standard_normal(MODEL.nv))
    com, chest, hand, _, posture, _ = _acceleration_tasks(state, rng)
    for task in (com, chest, hand):
        task.servo = AccelerationGains(6.0, 0.8)
    tasks = [com, chest, hand, posture]
    stack = TaskStack(MODEL.nv, tasks)
    H, c = np.full((MODEL.nv, MODEL.nv), np.nan), np.full(MODEL.nv, np.nan)
    stack.acceleration_objective(state, H, c, 1e-4)
    assert stack._acc_kd_uniform == pytest.approx(9.6)
    H_ref, c_ref = _generic_acceleration_objective(tasks, state, 1e-4)
    np.testing.assert_allclose(H, H_ref, rtol=1e-13, atol=1e-12)
    np.testing.assert_allclose(c, c_ref, rtol=1e-13, atol=1e-11)


def test_a_frame_on_the_free_root_has_a_constant_jacobian_and_no_drift():
    rng = np.random.default_rng(17)
    chest, hand = MODEL.getFrameId("chest"), MODEL.getFrameId("hand")
    first = DynamicsState(MODEL)
    assert first.on_free_root(chest) and not first.on_free_root(hand)
    task = FrameOrientationTask("chest", MODEL)
    J_0 = task.constant_acceleration_jacobian(first)
    assert J_0 is not None
    assert FrameOrientationTask("hand", MODEL).constant_acceleration_jacobian(first) is None
    for _ in range(5):
        state = DynamicsState(MODEL, random_q(MODEL, rng), 3.0 * rng.standard_normal(MODEL.nv))
        J, drift = task.jacobian_and_drift(state)
        np.testing.assert_allclose(J, J_0, atol=1e-15)
        assert np.abs(drift).max() < 1e-15
        assert np.abs(state.frame_drift(hand, pin.LOCAL)).max() > 0.1  # the arm's is not zero
    assert not DynamicsState(ARM).on_free_root(ARM.getFrameId("tip"))  # a fixed base


def test_a_dynamics_state_names_the_bad_input_and_keeps_q_and_v():
    """q and v share one buffer (one finiteness check): the error still names the bad one."""
    from mbctl.control.exceptions import TaskSetupError

    rng = np.random.default_rng(18)
    q, v = random_q(MODEL, rng), rng.standard_normal(MODEL.nv)
    state = DynamicsState(MODEL, q, v)
    np.testing.assert_array_equal(state.q, q)
    np.testing.assert_array_equal(state.v, v)
    bad_q, bad_v = q.copy(), v.copy()
    bad_q[2], bad_v[1] = np.nan, np.inf
    with pytest.raises(TaskSetupError, match="q must be finite"):
        state.update(bad_q, v)
    with pytest.raises(TaskSetupError, match=r"v must be finite .*got \[.*inf"):
        state.update(q, bad_v)
    with pytest.raises(TaskSetupError, match=rf"v must be a finite vector of shape \({MODEL.nv},\)"):
        state.update(q, v[:-1])
    state.update(q)  # v defaults to zero
    assert not state.v.any() and not state.q.flags.writeable


def test_a_dynamics_states_qv_is_q_then_v_and_read_only():
    """``qv`` is the one buffer behind q and v (the WBC's joint-limit bounds read it by one product)."""
    rng = np.random.default_rng(19)
    q, v = random_q(MODEL, rng), rng.standard_normal(MODEL.nv)
    state = DynamicsState(MODEL)
    state.update(q, v)
    np.testing.assert_array_equal(state.qv, np.concatenate([q, v]))
    assert not state.qv.flags.writeable
