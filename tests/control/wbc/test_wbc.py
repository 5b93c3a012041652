"""Whole-body inverse dynamics on a biped built in code (conftest.py), and the G1's static stance.

Task drifts against finite differences, static stance (forces under the CoM, friction, torque
limits), infeasibility (raised or the damping fallback), a closed-loop squat checked in MuJoCo,
the same torques whatever the actuator order, warm and cold starts, wrenches and CoP, M.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from mbctl.control import run
from mbctl.control.exceptions import TaskSetupError, WBCInfeasible, WBCSetupError
from mbctl.control.tasks import (
    AccelerationGains,
    AngularMomentumTask,
    ComTask,
    DampingTask,
    DynamicsState,
    FrameOrientationTask,
    FramePoseTask,
    FramePositionTask,
    PostureTask,
)
from mbctl.control.wbc import Scheduled, WBCConfig, standing_controller
from mbctl.robots.interface import RobotState
from mbctl.sim import Simulator
from mbctl.sim.monitor import PlantMonitor

FEET = ("l_sole", "r_sole")


def _tasks(model):
    targets = [ComTask(), FrameOrientationTask("torso", model), FramePoseTask("r_sole", model),
               FramePositionTask("chest", model), PostureTask(model)]
    for task in targets:
        task.set_target_from_state(DynamicsState(model))
    return [*targets, AngularMomentumTask()]


def test_every_task_drift_is_the_time_derivative_of_its_jacobian_times_v(tiny_biped):
    model = tiny_biped.pin_model
    rng = np.random.default_rng(3)
    lower, upper = model.lowerPositionLimit.clip(-3, 3), model.upperPositionLimit.clip(-3, 3)
    q = pin.randomConfiguration(model, lower, upper)
    v = rng.normal(size=model.nv)
    h = 1e-6
    for task in _tasks(model):
        states = [DynamicsState(model, pin.integrate(model, q, s * h * v), v) for s in (1.0, -1.0)]
        J, drift = task.jacobian_and_drift(DynamicsState(model, q, v))
        Jp, _ = task.jacobian_and_drift(states[0])
        Jm, _ = task.jacobian_and_drift(states[1])
        fd = (Jp @ v - Jm @ v) / (2 * h)
        scale = max(1.0, float(np.abs(fd).max()))
        assert np.abs(drift - fd).max() < 1e-6 * scale, task.name
        assert J.shape == (task.k, model.nv)


def test_every_fast_acceleration_path_equals_the_generic_rows(tiny_biped):
    """Each task's own write_acceleration_rows (a fast path) equals Task's generic one."""
    from mbctl.control.tasks import Task

    model = tiny_biped.pin_model
    rng = np.random.default_rng(11)
    q = pin.integrate(model, pin.neutral(model), 0.3 * rng.normal(size=model.nv))
    state = DynamicsState(model, q, rng.normal(size=model.nv))
    for task in _tasks(model):
        if hasattr(task, "set_target") and not isinstance(task, (ComTask, PostureTask)):
            task.set_target(pin.SE3(pin.exp3(0.2 * rng.normal(size=3)), rng.normal(size=3)))
        elif isinstance(task, ComTask):
            task.set_target(rng.normal(size=3), rng.normal(size=3), rng.normal(size=3))
        task.servo = AccelerationGains(7.0, 0.6)
        task.set_cost(rng.uniform(0.5, 2.0, task.k))
        fast = np.zeros((task.k, model.nv)), np.zeros(task.k)
        generic = np.zeros((task.k, model.nv)), np.zeros(task.k)
        task.write_acceleration_rows(state, *fast)
        Task.write_acceleration_rows(task, state, *generic)
        np.testing.assert_allclose(fast[0], generic[0], atol=1e-12, err_msg=task.name)
        np.testing.assert_allclose(fast[1], generic[1], atol=1e-10, err_msg=task.name)
    np.testing.assert_allclose(state.angular_momentum(), state.centroidal_map()[3:] @ state.v, atol=1e-12)


def test_contact_point_jacobian_is_the_points_velocity_in_the_foot_frame(tiny_biped):
    """G_F J_F v (in F, rotated to W) equals the finite difference of the points' world positions."""
    from mbctl.control.wbc import foot_contact_from_model
    from mbctl.control.wbc.contacts import ContactState

    model = tiny_biped.pin_model
    rng = np.random.default_rng(8)
    q = pin.integrate(model, pin.neutral(model), 0.4 * rng.normal(size=model.nv))
    v = rng.normal(size=model.nv)
    h = 1e-6
    for frame in FEET:
        foot = foot_contact_from_model(tiny_biped, frame)
        fid = model.getFrameId(frame)
        cs = ContactState(foot, fid, slice(0, 3 * foot.n_points), slice(2, 3 * foot.n_points, 3))

        def points_W(q_, fid=fid, foot=foot):
            X = DynamicsState(model, q_).frame_pose(fid)
            return foot.points_F @ X.rotation.T + X.translation

        fd = (points_W(pin.integrate(model, q, h * v)) - points_W(pin.integrate(model, q, -h * v))) / (2 * h)
        state = DynamicsState(model, q, v)
        v_F = (cs.G_F @ state.frame_jacobian(fid, pin.LOCAL) @ v).reshape(-1, 3)
        np.testing.assert_allclose(v_F @ state.frame_pose(fid).rotation.T, fd, atol=1e-7)


def test_the_stack_objective_equals_the_stacked_generic_rows(tiny_biped):
    """H = W^T W, c = -W^T r from every task's generic rows, the diagonal (posture) shortcut included."""
    from mbctl.control.tasks import Task
    from mbctl.control.tasks.stack import TaskStack

    model = tiny_biped.pin_model
    rng = np.random.default_rng(12)
    tasks = _tasks(model)
    for task in tasks:
        task.servo = AccelerationGains(6.0, 0.8)
    state = DynamicsState(model, pin.integrate(model, pin.neutral(model), 0.3 * rng.normal(size=model.nv)),
                          rng.normal(size=model.nv))
    H, c = np.zeros((model.nv, model.nv)), np.zeros(model.nv)
    TaskStack(model.nv, tasks).acceleration_objective(state, H, c)
    rows = [(np.zeros((t.k, model.nv)), np.zeros(t.k)) for t in tasks]
    for task, (W_t, r_t) in zip(tasks, rows, strict=True):
        Task.write_acceleration_rows(task, state, W_t, r_t)
    W, r = np.vstack([w for w, _ in rows]), np.concatenate([r for _, r in rows])
    np.testing.assert_allclose(H, W.T @ W, atol=1e-9)
    np.testing.assert_allclose(c, -W.T @ r, atol=1e-9)


def test_a_task_without_an_acceleration_form_is_named(tiny_biped, crouch):
    wb = standing_controller(tiny_biped, FEET, "pelvis")
    wb.hold(RobotState(crouch(tiny_biped), np.zeros(tiny_biped.nv), 0.0))
    wb.controller.add_task(DampingTask(tiny_biped.pin_model))
    with pytest.raises(TaskSetupError, match="damping: DampingTask has no acceleration-level form"):
        wb.controller.compute(RobotState(crouch(tiny_biped), np.zeros(tiny_biped.nv), 0.0))
    with pytest.raises(TaskSetupError, match="angular-momentum task has no velocity-level"):
        AngularMomentumTask().compute_error(wb.controller.state)


def _stance(robot, crouch, torso="torso", **config):
    wb = standing_controller(robot, FEET, "pelvis", torso, config=WBCConfig(**config))
    state = RobotState(crouch(robot), np.zeros(robot.nv), 0.0)
    wb.hold(state)
    return wb, state


def _check_static_stance(wb, state, mu):
    command = wb.controller.compute(state)
    sol, s = wb.controller.solution, wb.controller.state
    forces = np.vstack(list(sol.forces_W.values()))
    assert forces[:, 2].sum() == pytest.approx(s.mass * 9.81, rel=1e-6)
    # the centre of pressure of both feet together is under the centre of mass
    points = np.vstack(list(sol.points_W.values()))
    cop = forces[:, 2] @ points / forces[:, 2].sum()
    assert np.abs(cop[:2] - s.com()[:2]).max() < 1e-6
    # torques within the actuators' limits; every point inside its friction pyramid
    assert np.all(command.values <= wb.controller.tau_high + 1e-9)
    assert np.all(command.values >= wb.controller.tau_low - 1e-9)
    assert np.all(np.abs(forces[:, :2]) <= mu / np.sqrt(2) * forces[:, 2:3] + 1e-9)


def test_static_stance_forces_carry_the_weight_under_the_com(tiny_biped, crouch):
    _check_static_stance(*_stance(tiny_biped, crouch), mu=0.8)


def test_g1_static_stance(g1):
    from mbctl.robots.edits import position_to_motor
    from mbctl.robots.g1 import FEET as G1_FEET
    from mbctl.robots.g1 import PELVIS, TORSO, crouched_start

    robot = position_to_motor(g1)
    wb = standing_controller(robot, G1_FEET, PELVIS, TORSO)
    state = RobotState(crouched_start(robot), np.zeros(robot.nv), 0.0)
    wb.hold(state)
    _check_static_stance(wb, state, mu=0.6)


def test_infeasible_qp_raises_a_named_error_with_the_problem(tiny_biped, crouch):
    # 100 N per point (800 N on the ground, 3.6 m g) needs more than the knees' 120 N m
    wb, state = _stance(tiny_biped, crouch, f_min_n=100.0, f_max_n=400.0, relax_joint_limits=False)
    with pytest.raises(WBCInfeasible, match=(r"whole-body QP infeasible at step 0 \(solver daqp\): "
                                             r"contacts l_sole weight 1.00, r_sole weight 1.00; "
                                             r"normal force per point 100 to 400 N")) as info:
        wb.controller.compute(state)
    assert info.value.problem.P.shape == (wb.controller.n_x, wb.controller.n_x)
    assert info.value.result.found is False
    assert info.value.time_s == 0.0
    # the same stance with the default bounds is feasible
    wb.controller.config = WBCConfig()
    wb.controller.compute(state)


def test_an_infeasible_qp_is_solved_again_without_the_joint_limit_bounds(tiny_biped, crouch):
    # the stance above: the knees cannot hold 100 N per point at rest, and the joint-limit bounds
    # (the knees near their stop) forbid the acceleration that would relieve them
    wb, state = _stance(tiny_biped, crouch, f_min_n=100.0, f_max_n=400.0)
    ctrl = wb.controller
    command = ctrl.compute(state)
    assert ctrl.relaxed_cycles == 1 and not ctrl.fell_back
    sol = ctrl.solution
    tau = command.values
    assert np.all(tau <= ctrl.tau_high + 1e-6) and np.all(tau >= ctrl.tau_low - 1e-6)
    # the solution leaves the joint-limit bounds (that is what the relaxation allowed)...
    limits = ctrl._limits
    iv = limits.iv
    lo = np.minimum((limits.lower_scaled - 2.0 * (state.q[limits.iq]) / 0.1**2), 50.0)
    hi = np.maximum((limits.upper_scaled - 2.0 * (state.q[limits.iq]) / 0.1**2), -50.0)
    assert np.any((sol.vdot[iv] < lo - 1e-6) | (sol.vdot[iv] > hi + 1e-6))
    # ... and keeps every force bound: 100 N per point at least
    assert np.all(np.vstack(list(sol.forces_W.values()))[:, 2] >= 100.0 - 1e-6)
    # a feasible cycle counts nothing
    ctrl.config = WBCConfig()
    ctrl.compute(state)
    assert ctrl.relaxed_cycles == 1


def test_infeasible_qp_falls_back_to_joint_damping_when_asked(tiny_biped, crouch):
    wb, state = _stance(tiny_biped, crouch, f_min_n=100.0, f_max_n=400.0, on_infeasible="damp",
                        fallback_kd_n_m_s_rad=3.0, relax_joint_limits=False)
    moving = RobotState(state.q, np.linspace(-0.05, 0.05, tiny_biped.nv), 0.25)
    command = wb.controller.compute(moving)
    ctrl = wb.controller
    assert ctrl.fell_back and ctrl.infeasible_at_s == 0.25
    assert "whole-body QP infeasible at step 0" in ctrl.infeasible_message
    np.testing.assert_allclose(command.values, -3.0 * moving.v[ctrl.joints.idx_v], atol=1e-12)
    assert ctrl.solution.fallback and not np.any(np.vstack(list(ctrl.solution.forces_W.values())))
    # it stays in the fallback (a robot that lost its balance gets no QP torques mid-fall)
    ctrl.config = WBCConfig()
    ctrl.compute(state)
    assert ctrl.solution.fallback
    ctrl.reset()
    ctrl.compute(state)
    assert not ctrl.solution.fallback


def test_bad_options_are_named():
    with pytest.raises(WBCSetupError, match="f_max_n=0.5 is out of range"):
        WBCConfig(f_min_n=1.0, f_max_n=0.5)
    with pytest.raises(WBCSetupError, match="QP solver 'nope' is not installed"):
        WBCConfig(solver="nope")
    with pytest.raises(WBCSetupError, match="on_infeasible must be one of raise, damp; got 'fly'"):
        WBCConfig(on_infeasible="fly")
    for bad in (0.0, -0.01, float("nan")):
        with pytest.raises(WBCSetupError, match=rf"torsion_m={bad!r} is out of range \(> 0 m, or inf\)"):
            WBCConfig(torsion_m=bad)
    with pytest.raises(TaskSetupError, match="AccelerationGains.omega_rad_s must be finite and >= 0"):
        AccelerationGains(-1.0)


def test_unknown_foot_is_named(tiny_biped, crouch):
    wb, _ = _stance(tiny_biped, crouch)
    with pytest.raises(WBCSetupError, match="unknown foot 'hand'; feet: l_sole, r_sole"):
        wb.controller.release("hand")


def test_a_released_foot_leaves_no_row_and_no_stale_target(tiny_biped, crouch):
    """A released foot's slot in the feet's targets is refreshed, not rescaled, every cycle."""
    import warnings

    wb, state = _stance(tiny_biped, crouch)
    ctrl = wb.controller
    v = np.full(tiny_biped.nv, 0.01)  # the feet move: their targets are not zero
    ctrl.compute(RobotState(state.q, v, 0.0))
    ctrl.release("r_sole")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a stale target scaled by kp every cycle overflowed once
        for k in range(1, 2000):
            ctrl.compute(RobotState(state.q, v, 0.002 * k))
    assert ctrl.contact_released("r_sole")
    # the feet's targets in the QP: the left foot's rows, then the base's (moved over the right's)
    assert np.abs(ctrl._qp.e[:6]).max() < 10.0  # the damping of a 0.01 rad/s drift, not kp^k
    np.testing.assert_array_equal(ctrl._qp.e[6:12], -ctrl.state.b[:6])
    assert np.isfinite(ctrl.solution.tau).all()


@pytest.mark.parametrize("ramp_s", [0.05, 0.03, 0.3])
def test_a_release_ramp_ends_at_zero_weight_exactly(tiny_biped, crouch, ramp_s):
    """The ramp's steps round: periods of 2 ms summed from 3.072 s (a push while walking) took 0.05 s's
    ramp to 1.1e-13 after 25 steps. A weight within RAMP_SNAP of its target is the target, so the cycle
    that ends a release has the foot's forces pinned at zero, never bounded to [1e-13, 4e-11] N (a
    degenerate QP daqp reported infeasible, and the controller fell back to damping)."""
    wb, state = _stance(tiny_biped, crouch, ramp_s=ramp_s)
    ctrl = wb.controller
    cs = ctrl.contacts["r_sole"]
    t = 3.0719999999998833
    ctrl.compute(RobotState(state.q, state.v, t))
    ctrl.release("r_sole")
    weights = []
    for _ in range(200):
        t += 0.002
        ctrl.compute(RobotState(state.q, state.v, t))
        weights.append(cs.weight)
        if not cs.active:
            break
    assert weights[-1] == 0.0 and not cs.active
    assert all(w == 0.0 or w > 1e-6 for w in weights)  # no residue between the last step and zero
    assert len(weights) == round(ramp_s / 0.002)  # released on the ramp's last step, not one later
    right = ctrl.solution.force_slices["r_sole"]
    assert not ctrl._qp.force_free[right].any()


def test_a_released_foots_forces_are_pinned_and_the_solution_is_the_qps_optimum(tiny_biped, crouch):
    """At weight 0 a foot's force variables are pinned (the fast path leaves them out); the
    controller's solution is still the optimum of the whole QP it built (qpsolvers' daqp on it)."""
    import qpsolvers

    wb, state = _stance(tiny_biped, crouch)
    ctrl = wb.controller
    ctrl.compute(RobotState(state.q, state.v, 0.0))
    assert ctrl._qp.force_free.all()
    ctrl.release("r_sole")
    for k in range(1, 400):
        ctrl.compute(RobotState(state.q, state.v, 0.002 * k))
    assert ctrl.contact_released("r_sole")
    right = ctrl.solution.force_slices["r_sole"]
    left = ctrl.solution.force_slices["l_sole"]
    assert not ctrl._qp.force_free[right].any() and ctrl._qp.force_free[left].all()
    m_eq = ctrl._n_unact + 6  # the base rows and the left foot's
    reference = qpsolvers.solve_problem(ctrl._qp.problem(m_eq), solver="daqp").x
    x = np.concatenate([ctrl.solution.vdot, ctrl.solution.forces])
    np.testing.assert_allclose(x, reference, atol=1e-6 * np.abs(reference).max())
    np.testing.assert_allclose(ctrl.solution.forces[right], 0.0, atol=1e-6)


def test_the_biped_squats_in_mujoco(tiny_biped, crouch):
    """Closed loop on the plant: the CoM follows a 6 cm squat, measured with MuJoCo's CoM."""
    sim = Simulator(tiny_biped)
    sim.reset(q=crouch(tiny_biped))
    wb = standing_controller(tiny_biped, FEET, "pelvis", "torso")
    wb.hold(sim.read_state())
    c0 = wb.com.target
    w = np.pi

    def squat(t, state):
        wb.com.set_target(c0 - [0, 0, 0.03 * (1 - np.cos(w * t))], [0, 0, -0.03 * w * np.sin(w * t)],
                          [0, 0, -0.03 * w * w * np.cos(w * t)])

    plant = PlantMonitor(sim, {n: cs.contact.geoms for n, cs in wb.controller.contacts.items()}).attach()
    errors, forces, heights = [], [], []

    def measure(k, state, reference, command):
        errors.append(np.linalg.norm(plant.com_W - wb.com.target))
        forces.append(sum(c.normal_n for c in plant.contacts.values()))
        heights.append(plant.com_W[2])

    log = run(sim, Scheduled(wb.controller, squat), None, 2.0, on_step=measure)
    assert log.cycles == 1000
    assert np.sqrt(np.mean(np.square(errors))) < 2e-3  # measured 0.5 mm
    assert min(heights) == pytest.approx(c0[2] - 0.06, abs=2e-3)  # MuJoCo's CoM went 6 cm down
    assert np.median(forces) == pytest.approx(plant.mass_kg * 9.81, rel=0.05)
    assert sim.saturated_commands == 0


def _moving_state(robot, crouch, seed=5):
    rng = np.random.default_rng(seed)
    return RobotState(crouch(robot), 0.2 * rng.normal(size=robot.nv), 0.0)


def test_the_actuator_order_does_not_change_the_torques(tiny_biped, tiny_biped_reordered, crouch):
    # contiguous actuated dofs (slices) against an actuator order with no contiguous run (index
    # arrays): the same torques, joint by joint
    state = _moving_state(tiny_biped, crouch)
    torques = {}
    for label, robot in (("slices", tiny_biped), ("arrays", tiny_biped_reordered)):
        wb, _ = _stance(robot, crouch)
        command = wb.controller.compute(state)
        torques[label] = dict(zip(wb.controller.joints.joints, command.values, strict=True))
    assert list(torques["slices"]) != list(torques["arrays"])  # the orders differ
    for joint, tau in torques["slices"].items():
        assert torques["arrays"][joint] == pytest.approx(tau, abs=1e-7), joint
    assert max(abs(t) for t in torques["slices"].values()) > 1.0  # a loaded, moving state


def test_wrench_and_cop_agree_with_the_point_forces(tiny_biped, crouch):
    wb, _ = _stance(tiny_biped, crouch)
    wb.controller.compute(_moving_state(tiny_biped, crouch, seed=7))
    sol, s = wb.controller.solution, wb.controller.state
    for name, cs in wb.controller.contacts.items():
        X_WF = s.frame_pose(cs.fid)
        points = np.array([X_WF.act(p) for p in cs.contact.points_F])
        F = sol.forces_W[name]
        np.testing.assert_allclose(sol.points_W[name], points, atol=1e-12)
        moment = sum(np.cross(p - X_WF.translation, f) for p, f in zip(points, F, strict=True))
        np.testing.assert_allclose(sol.wrenches_W[name], np.concatenate([F.sum(0), moment]), atol=1e-9)
        np.testing.assert_allclose(sol.force_totals_W[name], F.sum(0), atol=1e-9)
        cop = sol.cop_W[name]
        lo, hi = points.min(0), points.max(0)
        assert np.all(cop[:2] >= lo[:2] - 1e-9) and np.all(cop[:2] <= hi[:2] + 1e-9), name
        # the CoP is where the moment of the normal forces about it vanishes
        assert abs(((points[:, :2] - cop[:2]) * F[:, 2:3]).sum(0)).max() < 1e-9
    # both feet's moment about a point (the CoM: the centroidal momentum's rate), and their total z
    c = np.array([0.03, -0.02, 0.5])
    moment, fz = sol.moment_about_W(c)
    F = np.vstack(list(sol.forces_W.values()))
    P = np.vstack(list(sol.points_W.values()))
    np.testing.assert_allclose(moment, np.cross(P - c, F).sum(0), atol=1e-9)
    assert fz == pytest.approx(F[:, 2].sum(), abs=1e-9) and fz > 100.0


def test_mass_matrix_is_symmetric_and_matches_crba(tiny_biped, crouch):
    model = tiny_biped.pin_model
    q = crouch(tiny_biped)
    s = DynamicsState(model, q, np.ones(model.nv))
    M = pin.crba(model, model.createData(), q)
    M = np.triu(M) + np.triu(M, 1).T
    np.testing.assert_allclose(s.M, M, atol=1e-10)
    assert not s.M.flags.writeable
    # the state copies data.M whole: Pinocchio's binding mirrors its upper triangle at every update,
    # whatever the lower one held
    s.data.M[np.tril_indices(model.nv, -1)] = 7.0
    q2 = pin.integrate(model, q, 0.1 * np.ones(model.nv))
    s.update(q2, np.ones(model.nv))
    M2 = pin.crba(model, model.createData(), q2)
    np.testing.assert_allclose(s.M, np.triu(M2) + np.triu(M2, 1).T, atol=1e-10)
    np.testing.assert_array_equal(s.M, s.M.T)


def test_a_joint_heading_for_its_limit_is_made_to_decelerate(tiny_biped, crouch):
    """The joint-limit bound demands deceleration before the limit (not only no acceleration toward it)."""
    wb, state = _stance(tiny_biped, crouch)
    ctrl = wb.controller
    knee = tiny_biped.joint("l_knee")
    q = np.array(state.q)
    q_lo = tiny_biped.pin_model.lowerPositionLimit[knee.idx_q]
    q[knee.idx_q] = q_lo + 0.06  # 0.06 rad above the lower limit, closing at 1 rad/s
    v = np.zeros(tiny_biped.nv)
    v[knee.idx_v] = -1.0
    ctrl.compute(RobotState(q, v, 0.0))
    cfg = ctrl.config
    Th = cfg.joint_limit_horizon_s
    required = 2.0 * (q_lo + cfg.joint_limit_margin_rad - (q[knee.idx_q] + v[knee.idx_v] * Th)) / Th**2
    assert required > 0.0  # coasting would cross the limit within the horizon
    assert ctrl.solution.vdot[knee.idx_v] >= min(required, cfg.joint_limit_max_accel_rad_s2) - 1e-6


@pytest.mark.parametrize("fixed", [False, True])
def test_centroidal_map_and_drift_equal_pinocchios(tiny_biped, fixed):
    """A_g and dA_g v from computeAllTerms' pass against computeCentroidalMapTimeVariation's."""
    model = tiny_biped.pin_model
    if fixed:  # a fixed-base robot (the CoM drift's float path needs a free-flyer root)
        model = pin.buildReducedModel(model, [1], pin.neutral(model))
    rng = np.random.default_rng(5)
    for _ in range(5):
        q = pin.integrate(model, pin.neutral(model), 0.5 * rng.normal(size=model.nv))
        v = rng.normal(size=model.nv)
        state = DynamicsState(model, q, v)
        data = model.createData()
        pin.computeCentroidalMapTimeVariation(model, data, q, v)
        np.testing.assert_allclose(state.centroidal_map(), data.Ag, atol=1e-12)
        np.testing.assert_allclose(state.centroidal_drift(), data.dAg @ v, atol=1e-10)
        assert state._free_root is not fixed
        # Jdot_com v: the CoM's acceleration at zero vdot, from Pinocchio's forward dynamics terms
        pin.centerOfMass(model, data, q, v, np.zeros(model.nv))
        fresh = DynamicsState(model, q, v)  # com_drift before centroidal_drift (its own path)
        np.testing.assert_allclose(fresh.com_drift(), data.acom[0], atol=1e-10)
        np.testing.assert_allclose(state.com_drift(), data.acom[0], atol=1e-10)


def test_foot_totals_and_cops_over_a_batch_are_each_solutions_own():
    from mbctl.control.wbc.config import foot_totals_and_cops_W

    rng = np.random.default_rng(6)
    points = rng.normal(0, 0.05, (4, 3))
    poses = [pin.SE3.Random() for _ in range(5)]
    forces_W = rng.normal(0, 20, (5, 4, 3)) + [0.0, 0.0, 60.0]  # pushing up, each point
    forces_W[1, :, 2] *= -1.0  # a foot pulled off the ground
    forces_W[3] = 0.0  # an unloaded one: neither has a centre of pressure
    forces = np.array([F @ X.rotation for F, X in zip(forces_W, poses, strict=True)])  # in F
    total, cop = foot_totals_and_cops_W(forces, np.array([X.homogeneous for X in poses]), points)
    for i, X in enumerate(poses):
        f_W = forces[i] @ X.rotation.T
        p_W = points @ X.rotation.T + X.translation
        np.testing.assert_allclose(total[i], f_W.sum(0), atol=1e-12)
        if f_W[:, 2].sum() <= 1e-6:  # a foot pulled off or unloaded (3)
            assert np.isnan(cop[i]).all()
        else:  # the CoP of the points' world-z forces, where the total's z is not ~0
            np.testing.assert_allclose(cop[i], f_W[:, 2] @ p_W / f_W[:, 2].sum(), rtol=1e-9, atol=1e-12)
    assert np.isfinite(cop).all(axis=1).tolist() == [True, False, True, False, True]
