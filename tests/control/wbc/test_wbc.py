"""Whole-body inverse dynamics: task drifts against finite differences, static stance, errors."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from mbctl.control.exceptions import WBCInfeasible, WBCSetupError
from mbctl.control.wbc import (
    AngularMomentumDamping,
    ComAcceleration,
    DynamicsState,
    FrameOrientationAcceleration,
    FramePoseAcceleration,
    FramePositionAcceleration,
    PostureAcceleration,
    TaskGains,
    WBCConfig,
)
from mbctl.jobs.g1_wbc import crouched_start, g1_whole_body
from mbctl.robots.edits import position_to_motor
from mbctl.robots.interface import RobotState


@pytest.fixture(scope="module")
def g1_motor(g1):
    from mbctl.jobs.robot_constants import with_palm_sites

    return position_to_motor(with_palm_sites(g1))


def _tasks(model, idx_v):
    gains = TaskGains(1.0)
    return [ComAcceleration(gains), FrameOrientationAcceleration("torso_link", model, gains),
            FramePoseAcceleration("right_foot", model, gains),
            FramePositionAcceleration("left_palm", model, gains),
            PostureAcceleration(model, idx_v, gains), AngularMomentumDamping(gains)]


def test_every_task_drift_is_the_time_derivative_of_its_jacobian_times_v(g1_motor):
    model = g1_motor.pin_model
    rng = np.random.default_rng(3)
    q = pin.randomConfiguration(model, -np.ones(model.nq) * 0 + model.lowerPositionLimit.clip(-3, 3),
                                model.upperPositionLimit.clip(-3, 3))
    v = rng.normal(size=model.nv)
    h = 1e-6
    for task in _tasks(model, np.arange(6, model.nv)):
        states = [DynamicsState(model, pin.integrate(model, q, s * h * v), v) for s in (1.0, -1.0)]
        center = DynamicsState(model, q, v)
        J, drift = task.jacobian_and_drift(center)
        Jp, _ = task.jacobian_and_drift(states[0])
        Jm, _ = task.jacobian_and_drift(states[1])
        fd = (Jp @ v - Jm @ v) / (2 * h)
        scale = max(1.0, float(np.abs(fd).max()))
        assert np.abs(drift - fd).max() < 1e-6 * scale, task.name
        assert J.shape == (task.k, model.nv)


def _stance_controller(robot):
    wb = g1_whole_body(robot)
    q = crouched_start(robot)
    state = RobotState(q, np.zeros(robot.pin_model.nv), 0.0)
    wb.hold(state)
    return wb, state


def test_static_stance_forces_carry_the_weight_under_the_com(g1_motor):
    wb, state = _stance_controller(g1_motor)
    command = wb.controller.compute(state)
    sol = wb.controller.solution
    s = wb.controller.state
    mg = s.mass * 9.81
    forces = np.vstack(list(sol.forces_W.values()))
    assert forces[:, 2].sum() == pytest.approx(mg, rel=1e-6)  # measured 2e-8
    # the centre of pressure of both feet together is under the centre of mass
    points = np.vstack([[s.frame_pose(cs.fid).act(p) for p in cs.contact.points_F]
                        for cs in wb.controller.contacts.values()])
    cop = forces[:, 2] @ points / forces[:, 2].sum()
    assert np.abs(cop[:2] - s.com()[:2]).max() < 1e-6
    # torques within the actuators' limits; every point inside its friction pyramid
    assert np.all(command.values <= wb.controller.tau_high + 1e-9)
    assert np.all(np.abs(forces[:, :2]) <= 0.6 / np.sqrt(2) * forces[:, 2:3] + 1e-9)


def test_infeasible_qp_raises_a_named_error_with_the_problem(g1_motor):
    wb, state = _stance_controller(g1_motor)
    # 100 N per point (800 N on the ground, 2.4 m g) needs more than the 139 N m the knees have
    wb.controller.config = WBCConfig(f_min_n=100.0, f_max_n=400.0)
    with pytest.raises(WBCInfeasible, match=(r"whole-body QP infeasible at step 0 \(solver daqp\): "
                                             r"contacts left_foot weight 1.00, right_foot weight 1.00; "
                                             r"normal force per point 100 to 400 N")) as info:
        wb.controller.compute(state)
    assert info.value.problem.P.shape == (wb.controller.n_x, wb.controller.n_x)
    assert info.value.result.found is False
    # the same stance with the default bounds is feasible
    wb.controller.config = WBCConfig()
    wb.controller.compute(state)


def test_bad_options_are_named():
    with pytest.raises(WBCSetupError, match="f_max_n=0.5 is out of range"):
        WBCConfig(f_min_n=1.0, f_max_n=0.5)
    with pytest.raises(WBCSetupError, match="QP solver 'nope' is not installed"):
        WBCConfig(solver="nope")
    with pytest.raises(WBCSetupError, match="TaskGains.weight must be finite and > 0"):
        TaskGains(0.0)


def test_unknown_foot_is_named(g1_motor):
    wb, _ = _stance_controller(g1_motor)
    with pytest.raises(WBCSetupError, match="unknown foot 'hand'; feet: left_foot, right_foot"):
        wb.controller.release("hand")


def _moving_state(robot, seed=5):
    rng = np.random.default_rng(seed)
    q = crouched_start(robot)
    return RobotState(q, 0.2 * rng.normal(size=robot.pin_model.nv), 0.0)


def test_slices_index_arrays_and_warm_start_give_the_same_solution(g1_motor):
    # the G1's base and actuated columns are contiguous, so the controller indexes with slices;
    # the index-array path (any actuator order) and a cold start must give the same torques
    state = _moving_state(g1_motor)
    wb, _ = _stance_controller(g1_motor)
    ctrl = wb.controller
    assert isinstance(ctrl._a, slice) and isinstance(ctrl._u, slice)
    ctrl.compute(state)
    ctrl.compute(state)  # warm-started from the first solve
    warm = ctrl.solution
    ctrl._a, ctrl._u = ctrl._act, ctrl._unact
    ctrl.config = WBCConfig(warm_start=False)
    ctrl.compute(state)
    cold = ctrl.solution
    np.testing.assert_allclose(cold.tau, warm.tau, atol=1e-7)
    np.testing.assert_allclose(cold.vdot, warm.vdot, atol=1e-7)
    assert np.abs(cold.tau).max() > 1.0  # a loaded, moving state, not a zero solution


def test_wrench_and_cop_agree_with_the_point_forces(g1_motor):
    wb, state = _stance_controller(g1_motor)
    wb.controller.compute(_moving_state(g1_motor, seed=7))
    sol = wb.controller.solution
    s = wb.controller.state
    for name, cs in wb.controller.contacts.items():
        X_WF = s.frame_pose(cs.fid)
        points = np.array([X_WF.act(p) for p in cs.contact.points_F])
        F = sol.forces_W[name]
        np.testing.assert_allclose(sol.points_W[name], points, atol=1e-12)
        moment = sum(np.cross(p - X_WF.translation, f) for p, f in zip(points, F, strict=True))
        np.testing.assert_allclose(sol.wrenches_W[name], np.concatenate([F.sum(0), moment]), atol=1e-9)
        cop = sol.cop_W[name]
        lo, hi = points.min(0), points.max(0)
        assert np.all(cop[:2] >= lo[:2] - 1e-9) and np.all(cop[:2] <= hi[:2] + 1e-9), name
        # the CoP is where the moment of the normal forces about it vanishes
        assert abs(((points[:, :2] - cop[:2]) * F[:, 2:3]).sum(0)).max() < 1e-9


def test_mass_matrix_is_symmetric_and_matches_crba(g1_motor):
    model = g1_motor.pin_model
    q = crouched_start(g1_motor)
    s = DynamicsState(model, q, np.ones(model.nv))
    M = pin.crba(model, model.createData(), q)
    M = np.triu(M) + np.triu(M, 1).T
    np.testing.assert_allclose(s.M, M, atol=1e-10)
    assert not s.M.flags.writeable
