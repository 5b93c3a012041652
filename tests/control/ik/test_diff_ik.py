"""Differential IK on Pinocchio: task Jacobians vs finite differences on the manifold, the QP
with daqp and OSQP, limits, unreachable targets and infeasibility."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
import qpsolvers

from mbctl.control import IKInfeasible, IKSetupError, TaskSetupError
from mbctl.control.ik import (
    Constraint,
    DiffIK,
    FloatingBaseVelocityLimit,
    JointPositionLimit,
    JointVelocityLimit,
    Limit,
    TwoLinkArm,
    solve_ik,
)
from mbctl.control.tasks import (
    ComTask,
    DampingTask,
    FrameOrientationTask,
    FramePoseTask,
    FramePositionTask,
    KinematicState,
    PostureTask,
    RelativeFrameTask,
    Task,
    Tolerance,
)
from mbctl.robots import UnknownNameError

SOLVERS = ["daqp", "osqp"]


def _random_q(model: pin.Model, rng: np.random.Generator, scale: float = 0.3, q0=None):
    q0 = pin.neutral(model) if q0 is None else q0
    return pin.integrate(model, q0, scale * rng.standard_normal(model.nv))


def _fd_jacobian(task, state: KinematicState, q: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """Central differences of e(q ⊕ h e_i) on the manifold."""
    model = state.model
    cols = []
    for i in range(model.nv):
        d = np.zeros(model.nv)
        d[i] = h
        state.update(pin.integrate(model, q, d))
        e_plus = np.array(task.compute_error(state))
        state.update(pin.integrate(model, q, -d))
        e_minus = np.array(task.compute_error(state))
        cols.append((e_plus - e_minus) / (2 * h))
    state.update(q)
    return np.column_stack(cols)


def _tasks_for(model: pin.Model, frame: str, state: KinematicState, rng: np.random.Generator):
    """Every task type, with targets away from the current pose (rotation included)."""
    X_WF = state.frame_pose(state.frame_id(frame))
    target = X_WF * pin.exp6(pin.Motion(0.05 * rng.standard_normal(6)))
    pose = FramePoseTask(frame, model, 1.0, 1.0)
    pose.set_target(target)
    pos = FramePositionTask(frame, model)
    pos.set_target(target.translation)
    ori = FrameOrientationTask(frame, model)
    ori.set_target(target)
    com = ComTask()
    com.set_target(state.com() + 0.03 * rng.standard_normal(3))
    posture = PostureTask(model)
    posture.set_target(_random_q(model, rng))
    # DampingTask is left out: its "Jacobian" is a regulariser, not de/dq (e is always 0).
    return [pose, pos, ori, com, posture]


def _check_fast_rows(task, state):
    """A task's write_qp_rows (fast path) equals the generic one from compute_error/jacobian."""
    task.lm_damping = 0.5
    task.gain = 0.7
    W_fast, r_fast = np.zeros((task.k, state.nv)), np.zeros(task.k)
    W_ref, r_ref = np.zeros((task.k, state.nv)), np.zeros(task.k)
    mu_fast = task.write_qp_rows(state, W_fast, r_fast)
    mu_ref = Task.write_qp_rows(task, state, W_ref, r_ref)
    np.testing.assert_allclose(W_fast, task.cost[:, None] * task.compute_jacobian(state),
                               atol=1e-13, rtol=0)
    np.testing.assert_allclose(W_fast, W_ref, atol=1e-13, rtol=0)
    np.testing.assert_allclose(r_fast, -0.7 * task.cost * task.compute_error(state), atol=1e-13)
    np.testing.assert_allclose(r_fast, r_ref, atol=1e-13, rtol=0)
    assert mu_fast == pytest.approx(mu_ref, abs=1e-13)
    task.lm_damping = 0.0
    task.gain = 1.0


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_task_jacobians_match_finite_differences_two_link(two_link, seed):
    rng = np.random.default_rng(seed)
    model = two_link.pin_model
    q = _random_q(model, rng, 1.0)
    state = KinematicState(model, q)
    for task in _tasks_for(model, "end_effector", state, rng):
        e, J = task.error_and_jacobian(state)
        np.testing.assert_allclose(e, task.compute_error(state), atol=1e-14, rtol=0)
        np.testing.assert_allclose(J, task.compute_jacobian(state), atol=1e-14, rtol=0)
        _check_fast_rows(task, state)
        err = np.max(np.abs(J - _fd_jacobian(task, state, q)))
        assert err < 1e-7, f"{task.name}: |J - J_fd|_inf = {err:.2e}"


@pytest.mark.parametrize("seed", [0, 1])
def test_task_jacobians_match_finite_differences_g1(g1, seed):
    rng = np.random.default_rng(seed)
    model = g1.pin_model
    q = _random_q(model, rng, 0.3, g1.keyframe_q("stand"))
    state = KinematicState(model, q)
    for frame in ("left_foot", "pelvis", "right_wrist_yaw_link"):
        for task in _tasks_for(model, frame, state, rng):
            _check_fast_rows(task, state)
            err = np.max(np.abs(task.compute_jacobian(state) - _fd_jacobian(task, state, q)))
            assert err < 1e-6, f"{task.name} on {frame}: |J - J_fd|_inf = {err:.2e}"


def test_pose_task_jacobian_at_zero_relative_rotation(g1):
    # Pure-translation error (the palm-target case): Jlog6 keeps its -[p]x/2 block.
    model = g1.pin_model
    q = g1.keyframe_q("stand")
    state = KinematicState(model, q)
    task = FramePoseTask("left_wrist_yaw_link", model, 1.0, 0.0)
    X = pin.SE3(state.frame_pose(state.frame_id("left_wrist_yaw_link")))
    X.translation = X.translation + np.array([0.1, 0.0, 0.0])
    task.set_target(X)
    assert np.max(np.abs(task.compute_jacobian(state) - _fd_jacobian(task, state, q))) < 1e-7


def test_damping_task_adds_cost_squared_on_joint_diagonal(g1):
    model = g1.pin_model
    cost = np.linspace(0.1, 1.0, model.nv)
    ik = DiffIK(model, [DampingTask(model, cost)], damping=0.0)
    ik.update(g1.keyframe_q("stand"))
    problem = ik.build_problem(1.0)
    expected = cost**2
    expected[:6] = 0.0  # floating base left free, as in mink
    np.testing.assert_allclose(problem.P, np.diag(expected), atol=1e-15)
    np.testing.assert_array_equal(problem.q, np.zeros(model.nv))


@pytest.mark.parametrize("solver", SOLVERS)
def test_two_link_reaches_target_with_each_solver(two_link, solver):
    model = two_link.pin_model
    arm = TwoLinkArm.from_robot(two_link)
    target = np.array([*arm.forward_kinematics([0.4, 1.2]), 0.0])
    task = FramePositionTask("end_effector", model, cost=1.0)
    task.set_target(target)
    ik = DiffIK(model, [task, DampingTask(model, 1e-3)], [JointVelocityLimit(model, {
        "shoulder": 2.0, "elbow": 2.0})], solver=solver)
    res = ik.solve(np.array([0.1, 0.5]), dt=0.5, tolerance=Tolerance(1e-8))
    assert res.converged and not res.stalled
    assert res.iterations <= 8
    assert res.residuals["end_effector position"].position_m < 1e-8
    np.testing.assert_allclose(arm.forward_kinematics(res.q), target[:2], atol=1e-8)
    # velocity limit: every step within v_max dt = 1 rad
    assert np.all(res.step_norms <= 1.0 + 1e-7)


def test_daqp_and_osqp_give_the_same_step(g1):
    model = g1.pin_model
    rng = np.random.default_rng(3)
    q = _random_q(model, rng, 0.2, g1.keyframe_q("stand"))
    state = KinematicState(model, q)
    tasks = _tasks_for(model, "left_foot", state, rng)
    limits = [JointPositionLimit(model), FloatingBaseVelocityLimit(model, 0.5, 1.0)]
    v = {s: DiffIK(model, tasks, limits, s, damping=1e-3).step(q, 0.1).v for s in SOLVERS}
    assert np.max(np.abs(v["daqp"] - v["osqp"])) < 1e-5
    # the functional form gives the daqp answer
    np.testing.assert_allclose(
        solve_ik(state, tasks, 0.1, "daqp", 1e-3, limits), v["daqp"], atol=1e-12, rtol=0
    )


def test_unreachable_target_converges_to_closest_pose(two_link):
    model = two_link.pin_model
    arm = TwoLinkArm.from_robot(two_link)
    task = FramePositionTask("end_effector", model, cost=1.0, lm_damping=1.0)
    task.set_target([0.9, 0.0, 0.0])
    ik = DiffIK(model, [task, DampingTask(model, 1e-2)], [JointVelocityLimit(model, {
        "shoulder": 2.0, "elbow": 2.0})])
    res = ik.solve(np.array([0.1, 0.5]), dt=0.5, tolerance=Tolerance(1e-6), max_iters=200)
    assert not res.converged and res.stalled
    residual = res.residuals["end_effector position"].position_m
    assert residual == pytest.approx(0.9 - arm.r_max, abs=1e-6)


def test_joint_position_limits_hold_on_g1(g1):
    model = g1.pin_model
    q0 = g1.keyframe_q("stand")
    state = KinematicState(model, q0)
    task = FramePositionTask("left_wrist_yaw_link", model, cost=1.0, lm_damping=1.0)
    task.set_target(state.frame_pose(state.frame_id("left_wrist_yaw_link")).translation
                    + [0.0, 1.0, 1.0])  # far out of reach: limits must bind
    limit = JointPositionLimit(model)
    ik = DiffIK(model, [task, DampingTask(model, 1e-2)], [limit, FloatingBaseVelocityLimit(
        model, 1e-9, 1e-9)])
    res = ik.solve(q0, dt=1.0, max_iters=40)
    assert not res.converged
    qj = res.q[limit.idx_q]
    assert np.all(qj >= limit.q_min - 1e-9) and np.all(qj <= limit.q_max + 1e-9)
    assert min(min(m) for m in limit.margins(res.q).values()) < 1e-2  # some joint hit a limit
    np.testing.assert_allclose(res.q[:7], q0[:7], atol=1e-7)  # base pinned by its limit


def test_floating_base_velocity_limit_bounds_local_twist(g1):
    model = g1.pin_model
    q0 = g1.keyframe_q("stand")
    state = KinematicState(model, q0)
    task = FramePoseTask("pelvis", model, 1.0, 1.0)
    task.set_target(state.frame_pose(state.frame_id("pelvis")) * pin.exp6(pin.Motion(
        np.array([0.5, -0.5, 0.2, 0.3, -0.3, 0.4]))))
    lim = FloatingBaseVelocityLimit(model, linear=0.1, angular=[0.2, 0.2, 0.05])
    step = DiffIK(model, [task], [lim]).step(q0, dt=0.5)
    bound = lim.max_velocity * 0.5
    assert np.all(np.abs(step.dq[:6]) <= bound + 1e-9)
    assert np.any(np.abs(step.dq[:6]) >= bound - 1e-9)  # active


@pytest.mark.parametrize("solver", SOLVERS)
def test_contradictory_bounds_raise_ik_infeasible(two_link, solver):
    model = two_link.pin_model
    limited = model.copy()
    limited.lowerPositionLimit = np.array([-1.0, -1.0])
    limited.upperPositionLimit = np.array([1.0, 1.0])
    task = FramePositionTask("end_effector", limited)
    task.set_target([0.3, 0.3, 0.0])
    ik = DiffIK(limited, [task], [JointPositionLimit(limited), JointVelocityLimit(
        limited, {"shoulder": 0.1, "elbow": 0.1})], solver=solver)
    with pytest.raises(IKInfeasible) as info:
        ik.step(np.array([2.0, 0.0]), dt=1.0)  # shoulder 1 rad beyond its upper limit
    exc = info.value
    assert isinstance(exc.problem, qpsolvers.Problem)
    assert exc.result.found is False
    assert exc.problem.lb[0] > exc.problem.ub[0]
    assert "dofs [0]" in str(exc) and "outside its joint limits" in str(exc)


class _ContradictoryLimit(Limit):
    """dq_0 <= -1 and dq_0 >= 1."""

    def compute_qp_inequalities(self, state, dt):
        G = np.zeros((2, state.nv))
        G[0, 0], G[1, 0] = 1.0, -1.0
        return Constraint(G, np.array([-1.0, -1.0]))


@pytest.mark.parametrize("solver", SOLVERS)
def test_infeasible_qp_reported_by_solver_raises_ik_infeasible(two_link, solver):
    model = two_link.pin_model
    task = FramePositionTask("end_effector", model)
    task.set_target([0.3, 0.3, 0.0])
    ik = DiffIK(model, [task], [_ContradictoryLimit()], solver=solver)
    with pytest.raises(IKInfeasible, match=f"QP solver '{solver}' found no IK step") as info:
        ik.step(np.array([0.2, 0.3]))
    assert info.value.solver == solver
    assert info.value.result.found is False
    np.testing.assert_array_equal(info.value.problem.h, [-1.0, -1.0])


def test_setup_errors(two_link):
    model = two_link.pin_model
    with pytest.raises(UnknownNameError, match="Unknown frame 'end_efector'.*end_effector"):
        FramePoseTask("end_efector", model)
    with pytest.raises(TaskSetupError, match="position_cost must be a non-negative"):
        FramePoseTask("end_effector", model, position_cost=-1.0)
    with pytest.raises(TaskSetupError, match="gain must be in \\[0, 1\\]; got 1.5"):
        FramePositionTask("end_effector", model, gain=1.5)
    with pytest.raises(IKSetupError, match="QP solver 'nosuch' is not installed; available:"):
        DiffIK(model, [DampingTask(model)], solver="nosuch")
    with pytest.raises(IKSetupError, match="needs a free-flyer joint"):
        FloatingBaseVelocityLimit(model)
    with pytest.raises(TaskSetupError, match="no target set"):
        DiffIK(model, [FramePositionTask("end_effector", model)]).step(np.zeros(2))
    with pytest.raises(UnknownNameError, match="Unknown joint 'wrist'"):
        JointVelocityLimit(model, {"wrist": 1.0})


TINY_MJCF = """
<mujoco model="tiny">
  <compiler angle="radian" autolimits="true" inertiafromgeom="false"/>
  <worldbody>
    <body name="base" pos="0 0 1">
      <freejoint name="root"/>
      <inertial pos="0 0 0" mass="2" diaginertia="0.1 0.1 0.1"/>
      <body name="shoulder" pos="0.1 0 0">
        <joint name="ball" type="ball"/>
        <inertial pos="0.1 0 0" mass="1" diaginertia="0.01 0.01 0.01"/>
        <body name="slider" pos="0.2 0 0">
          <joint name="slide" type="slide" axis="1 0 0" range="-0.1 0.2"/>
          <inertial pos="0 0 0" mass="0.5" diaginertia="0.01 0.01 0.01"/>
          <body name="hand" pos="0.1 0 0">
            <joint name="wrist" type="hinge" axis="0 1 0" range="-1 1"/>
            <inertial pos="0.05 0 0" mass="0.3" diaginertia="0.001 0.001 0.001"/>
            <site name="tip" pos="0.1 0 0.02"/>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    from mbctl.robots import load_robot

    path = tmp_path_factory.mktemp("tiny") / "tiny.xml"
    path.write_text(TINY_MJCF)
    return load_robot(path)


def test_any_robot_free_ball_slide_hinge_fd_and_solve(tiny):
    """A model in code with every joint kind: Jacobians on the manifold and a solve to target."""
    model = tiny.pin_model
    rng = np.random.default_rng(7)
    q = _random_q(model, rng, 0.4)
    q[-2:] = [0.02, 0.3]  # slide and wrist inside their ranges
    state = KinematicState(model, q)
    for task in _tasks_for(model, "tip", state, rng):
        _check_fast_rows(task, state)
        err = np.max(np.abs(task.compute_jacobian(state) - _fd_jacobian(task, state, q)))
        assert err < 1e-6, f"{task.name}: |J - J_fd|_inf = {err:.2e}"
    limit = JointPositionLimit(model)
    assert limit.joint_names == ("slide", "wrist")  # ball and free joints are not boxes
    # a reachable target: the tip pose at another joint configuration, same base pose
    dq_joints = np.r_[np.zeros(6), 0.3, -0.2, 0.25, 0.05, 0.4]
    goal = KinematicState(model, pin.integrate(model, q, dq_joints))
    target = goal.frame_pose(goal.frame_id("tip"))
    pose = FramePoseTask("tip", model, 1.0, 1.0)
    pose.set_target(target)
    base = FramePoseTask("base", model, 10.0, 10.0)  # hold the floating base
    base.set_target_from_state(state)
    ik = DiffIK(model, [pose, base, DampingTask(model, 1e-3)],
                [limit, FloatingBaseVelocityLimit(model, 0.5, 1.0)])
    res = ik.solve(q, dt=1.0, tolerance=Tolerance(1e-6, 1e-6), max_iters=50)
    assert res.converged, res.residuals
    qj = res.q[limit.idx_q]
    assert np.all(qj >= limit.q_min - 1e-9) and np.all(qj <= limit.q_max + 1e-9)
    quat = res.q[3:7]  # manifold integration keeps the free-flyer quaternion unit
    assert abs(np.linalg.norm(quat) - 1.0) < 1e-12


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_relative_frame_task_jacobian_matches_finite_differences_on_a_floating_base(g1, seed):
    """The palm's pose in the torso frame (both move, the base floats): J_e = Jlog6 (J_F - Ad J_R)."""
    rng = np.random.default_rng(seed)
    model = g1.pin_model
    q = _random_q(model, rng, 0.3, g1.keyframe_q("stand"))
    state = KinematicState(model, q)
    task = RelativeFrameTask("left_wrist_yaw_link", "torso_link", model, 1.0, [0.5, 1.0, 2.0])
    task.set_target(pin.exp6(pin.Motion(0.2 * rng.standard_normal(6))))
    J = task.compute_jacobian(state)
    assert np.max(np.abs(J - _fd_jacobian(task, state, q))) < 1e-7
    # the frame and the reference moving together (the base alone) leave the error unchanged
    np.testing.assert_allclose(J[:, :6], 0.0, atol=1e-12)
    # the residual is the pose error in the reference frame; no acceleration-level form
    X_RF = state.frame_pose(state.frame_id("torso_link")).actInv(state.frame_pose(state.frame_id(
        "left_wrist_yaw_link")))
    res = task.residual(state)
    assert res.position_m == pytest.approx(np.linalg.norm(task.transform_target_to_world.actInv(
        X_RF).translation))
    with pytest.raises(TaskSetupError, match="no acceleration-level form"):
        task.jacobian_and_drift(state)


@pytest.mark.parametrize("seed", [0, 1])
def test_velocity_rows_are_the_active_rows_of_the_task(g1, seed):
    """Every task's unweighted velocity rows are its active rows of ``(J_e, e)``, or both negated."""
    rng = np.random.default_rng(seed)
    model = g1.pin_model
    q = _random_q(model, rng, 0.3, g1.keyframe_q("stand"))
    state = KinematicState(model, q)
    tasks = _tasks_for(model, "left_foot", state, rng)
    partial = FramePoseTask("left_foot", model, [1.0, 0.0, 2.0], 0.0)  # zero-cost rows dropped
    partial.set_target(tasks[0].transform_target_to_world)
    relative = RelativeFrameTask("left_foot", "pelvis", model, 1.0, 0.0)
    relative.set_target_from_state(state)
    com = ComTask([1.0, 1.0, 0.0])
    com.set_target(state.com() + 0.01)
    for task in [*tasks[:3], partial, relative, com]:
        rows = task.active_rows()
        J_out, e_out = np.zeros((len(rows), model.nv)), np.zeros(len(rows))
        task.write_velocity_rows(state, J_out, e_out)
        e, J = task.error_and_jacobian(state)
        sign = 1.0 if np.allclose(e_out, e[rows], atol=1e-14) else -1.0
        np.testing.assert_allclose(e_out, sign * e[rows], atol=1e-14, err_msg=task.name)
        np.testing.assert_allclose(J_out, sign * J[rows], atol=1e-12, err_msg=task.name)
    assert partial.active_rows().tolist() == [0, 2] and com.active_rows().tolist() == [0, 1]
