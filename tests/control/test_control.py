"""Controllers, gains and the control loop (plant = MuJoCo, model = Pinocchio)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from mbctl.control.computed_torque import ComputedTorque
from mbctl.control.controller import (
    Controller,
    ControllerBase,
    JointMap,
    JointReference,
    joint_reference,
    task_reference,
)
from mbctl.control.exceptions import (
    ControlError,
    ControllerSetupError,
    GainsError,
    ReferenceMismatch,
)
from mbctl.control.gains import PDGains, gains_from_frequency
from mbctl.control.ik.two_link import TwoLinkArm
from mbctl.control.loop import presample, run
from mbctl.control.pd import JointPD
from mbctl.control.pd_gravity import PDGravity
from mbctl.control.position_pd import PositionTargetPD
from mbctl.control.task_space import TaskSpaceComputedTorque
from mbctl.exceptions import ToolkitError
from mbctl.planners.trajectory import JointTrajectory
from mbctl.robots.commands import CommandKind
from mbctl.robots.exceptions import CommandError, UnknownNameError
from mbctl.robots.registry import load_robot
from mbctl.sim.simulator import Simulator


@pytest.fixture(scope="module")
def two_link_gravity_pos():
    """The 2-link arm with position actuators and in-plane gravity."""
    return load_robot("two_link", gravity=True)


# ------------------------------------------------------------------------------------ gains
def test_gains_from_frequency_follow_inertia_omega_zeta():
    g = gains_from_frequency([10.0, 20.0], 0.7, [0.5, 2.0])
    np.testing.assert_allclose(g.kp, [0.5 * 100.0, 2.0 * 400.0])
    np.testing.assert_allclose(g.kd, [2 * 0.7 * 0.5 * 10.0, 2 * 0.7 * 2.0 * 20.0])
    unit = gains_from_frequency(30.0)
    np.testing.assert_allclose([unit.kp[0], unit.kd[0]], [900.0, 60.0])


def test_gains_are_read_only_and_frozen():
    g = PDGains([1.0, 2.0], [0.1, 0.2])
    with pytest.raises(ValueError):
        g.kp[0] = 5.0
    with pytest.raises(AttributeError):
        g.kp = np.zeros(2)  # type: ignore[misc]


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: PDGains([1.0, -2.0], [0.1, 0.2]),
         "kp must be finite and >= 0; got [-2.0] at joint indices [1]"),
        (lambda: PDGains([1.0, 2.0], [0.1]),
         "kp and kd must have the same length (one per joint); got 2 and 1"),
        (lambda: PDGains([1.0], [np.nan]), "kd must be finite and >= 0; got [nan] at joint indices [0]"),
        (lambda: PDGains([], []), "kp must have at least one value; got an empty vector"),
        (lambda: gains_from_frequency(0.0, 1.0, 1.0),
         "omega_rad_s must be finite and > 0; got [0.0] at indices [0]"),
        (lambda: gains_from_frequency(10.0, -0.1, 1.0),
         "zeta must be finite and >= 0; got [-0.1] at indices [0]"),
        (lambda: gains_from_frequency(10.0, 1.0, [1.0, 0.0]),
         "inertia must be finite and > 0; got [0.0] at indices [1]"),
        (lambda: gains_from_frequency([1.0, 2.0], 1.0, [1.0, 2.0, 3.0]),
         "omega_rad_s, zeta and inertia must be numbers or vectors of one length; got [1.0, 2.0], 1.0, "
         "[1.0, 2.0, 3.0]"),
        (lambda: PDGains([1.0, 2.0], [1.0, 2.0]).broadcast(3),
         "gains cover 2 joints; the controller has 3 joints"),
    ],
)
def test_gains_validation_names_the_bad_value(make, message):
    """The whole message: the bad value, where it is, and what was expected; GainsError itself."""
    with pytest.raises(GainsError) as info:
        make()
    assert type(info.value) is GainsError
    assert str(info.value) == message


def test_control_errors_share_the_toolkit_root():
    """One except clause (the CLI's) catches every control error: checked once, for each class."""
    import inspect

    from mbctl.control import exceptions

    classes = [c for _, c in inspect.getmembers(exceptions, inspect.isclass)
               if c.__module__ == exceptions.__name__]
    assert GainsError in classes and len(classes) >= 4
    assert all(issubclass(c, ControlError) and issubclass(c, ToolkitError) for c in classes)


# ------------------------------------------------------------------------------------ setup
def test_joint_map_and_setup_errors(two_link_torque):
    jm = JointMap.from_robot(two_link_torque)
    assert jm.joints == ("shoulder", "elbow")
    assert jm.covers_all_actuators and jm.command_names is None
    np.testing.assert_allclose(jm.tau_low, [-30.0, -20.0])
    partial = JointMap.from_robot(two_link_torque, ["elbow"])
    assert partial.command_names == ("elbow",)
    with pytest.raises(UnknownNameError):
        JointMap.from_robot(two_link_torque, ["elbo"])
    with pytest.raises(ControllerSetupError, match="distinct"):
        JointMap.from_robot(two_link_torque, ["elbow", "elbow"])
    with pytest.raises(ControllerSetupError, match="every dof"):
        ComputedTorque(two_link_torque, gains_from_frequency(10.0), ["elbow"])
    with pytest.raises(ControllerSetupError, match="position actuators"):
        PositionTargetPD(two_link_torque)
    with pytest.raises(ReferenceMismatch):
        joint_reference([0.0, 1.0], v=[0.0])


def test_controllers_compute_their_law_as_a_command_from_a_robot_state(
    two_link_torque_gravity, two_link_gravity_pos
):
    """What the Controller protocol promises, by behaviour: from a RobotState and a reference,
    ``compute`` returns a Command of the actuators' kind, one value per actuator, equal to the
    controller's law (recomputed here from Robot's M, b, g and J); ``reset`` clears the clip
    counters. The 2-link arm with gravity on, so g(q) and the velocity terms are not zero."""
    from mbctl.robots.interface import RobotState

    robot = two_link_torque_gravity
    gains = gains_from_frequency(10.0)  # kp = 100 [1/s^2], kd = 20 [1/s]
    kp, kd = gains.kp, gains.kd
    state = RobotState(np.array([0.3, -0.5]), np.array([0.2, 0.1]), 0.0)
    ref = JointReference(np.array([0.35, -0.45]), np.array([0.0, 0.3]), np.array([1.0, -1.0]))
    q, v = state.q, state.v
    fb = kp * (ref.q - q) + kd * (ref.v - v)
    M, b, g = robot.mass_matrix(q), robot.bias(q, v), robot.gravity(q)
    assert np.abs(g).min() > 0.1 and np.abs(b - g).min() > 1e-4  # the terms are really there

    # task space on the end effector's x-y: J a = a_task - dJ v, with dJ v by central differences
    p_ref, pv_ref, pa_ref = np.array([0.5, 0.2]), np.array([0.1, 0.0]), np.array([0.0, 0.5])
    J = robot.jacobian("end_effector", q)[:2]
    h = 1e-6
    dJv = (robot.jacobian("end_effector", q + h * v)[:2]
           - robot.jacobian("end_effector", q - h * v)[:2]) @ v / (2 * h)
    p = robot.frame_pose("end_effector", q)[0][:2]
    a_task = pa_ref + kp * (p_ref - p) + kd * (pv_ref - J @ v)
    cases: list[tuple[Controller, object, np.ndarray]] = [
        (JointPD(robot, gains), ref, fb),
        (PDGravity(robot, gains), ref, fb + g),
        (ComputedTorque(robot, gains), ref, M @ (ref.a + fb) + b),
        (TaskSpaceComputedTorque(robot, gains), task_reference(p_ref, pv_ref, pa_ref),
         M @ np.linalg.solve(J, a_task - dJv) + b),
    ]
    for controller, reference, tau in cases:
        cmd = controller.compute(state, reference)
        name = type(controller).__name__
        assert cmd.kind is CommandKind.TORQUE and cmd.names is None, name  # every actuator, in order
        assert cmd.values.shape == (robot.nu,), name
        assert np.abs(tau).max() < 20.0, name  # inside the torque limits: nothing clipped
        np.testing.assert_allclose(cmd.values, tau, rtol=1e-7, atol=1e-9, err_msg=name)

    # position actuators: target u = q_ref + (kv v_ref + g) / kp, kp and kv the actuators' own
    pos_robot = two_link_gravity_pos
    kp_act = np.array([pos_robot.actuator(n).kp for n in ("shoulder", "elbow")])
    kv_act = np.array([pos_robot.actuator(n).kv for n in ("shoulder", "elbow")])
    cmd = PositionTargetPD(pos_robot).compute(state, ref)
    assert cmd.kind is CommandKind.POSITION and cmd.values.shape == (pos_robot.nu,)
    np.testing.assert_allclose(cmd.values, ref.q + (kv_act * ref.v + pos_robot.gravity(q)) / kp_act,
                               rtol=1e-12, atol=1e-12)
    # ... or the plant's own gains (a robot over DDS may lower them): the same torque under them
    pd = PositionTargetPD(pos_robot)
    pd.use_gains(dict(zip(pd.joints, [(50.0, 1.0), (20.0, 0.5)], strict=True)))
    cmd = pd.compute(state, ref)
    kp, kv = np.array([50.0, 20.0]), np.array([1.0, 0.5])
    np.testing.assert_allclose(cmd.values, ref.q + (kv * ref.v + pos_robot.gravity(q)) / kp, rtol=1e-12,
                               atol=1e-12)
    with pytest.raises(ControllerSetupError, match=r"no gains for .*; kp <= 0 on "):
        pd.use_gains({pd.joints[0]: (0.0, 1.0)})

    # reset() clears the clip counters a saturated command left behind
    pd = JointPD(robot, gains)
    cmd = pd.compute(state, JointReference(np.array([3.0, -3.0]), np.zeros(2), np.zeros(2)))
    np.testing.assert_array_equal(cmd.values, [30.0, -20.0])  # clipped to the motors' ctrlrange
    assert pd.saturation.saturated_cycles == 1 and pd.saturation.by_joint() == {"shoulder": 1,
                                                                                "elbow": 1}
    pd.reset()
    assert pd.saturation.saturated_cycles == 0 and pd.saturation.by_joint() == {}


# ------------------------------------------------------------------------------------ laws
def test_computed_torque_inverts_the_plant_dynamics(two_link_torque_gravity):
    """With zero feedback, CT torques give the plant exactly the reference acceleration."""
    robot = two_link_torque_gravity
    ct = ComputedTorque(robot, PDGains([0.0], [0.0]), saturate=False)
    sim = Simulator(robot)
    rng = np.random.default_rng(0)
    for _ in range(5):
        q, v, a = rng.uniform(-1, 1, 2), rng.uniform(-2, 2, 2), rng.uniform(-5, 5, 2)
        sim.reset(q=q, v=v)
        cmd = ct.compute(sim.read_state(), JointReference(q, v, a))
        sim.send(cmd)
        mujoco.mj_forward(sim.model, sim.data)
        np.testing.assert_allclose(sim.data.qacc, a, atol=1e-9)


def test_pd_gravity_holds_a_pose_pd_sags(two_link_torque_gravity):
    robot = two_link_torque_gravity
    q_ref = np.array([0.3, 0.6])
    gains = gains_from_frequency(20.0, 1.0, [0.19, 0.03])
    errors = {}
    for c in (JointPD(robot, gains), PDGravity(robot, gains)):
        sim = Simulator(robot)
        sim.reset(q=q_ref)
        log = run(sim, c, joint_reference(q_ref), 2.0)
        errors[c.name] = np.abs(log.q[-1] - q_ref).max()
    assert errors["pd_gravity"] < 1e-4 < 1e-2 < errors["pd"]


def test_task_space_ct_reaches_a_point(two_link_torque_gravity):
    robot = two_link_torque_gravity
    arm = TwoLinkArm.from_robot(robot)
    sim = Simulator(robot)
    sim.reset(q=[0.4, 1.2])
    target = arm.forward_kinematics([0.4, 1.2]) + np.array([0.05, -0.03])
    c = TaskSpaceComputedTorque(robot, gains_from_frequency(20.0))
    run(sim, c, task_reference(target), 1.5)
    sim.forward()
    p, _ = sim.site_pose("end_effector")
    np.testing.assert_allclose(p[:2], target, atol=1e-5)
    with pytest.raises(ReferenceMismatch):
        c.compute(sim.read_state(), task_reference([0.1, 0.2, 0.3]))


def test_saturation_is_counted_and_clipped(two_link_torque):
    c = JointPD(two_link_torque, PDGains([1e4], [0.0]))
    sim = Simulator(two_link_torque)
    sim.reset(q=[0.0, 0.0])
    log = run(sim, c, joint_reference([1.0, -1.0]), 0.02)
    assert c.saturation.saturated_cycles > 0
    assert c.saturation.by_joint()["shoulder"] > 0
    assert np.all(log.command[:, 0] <= 30.0) and np.all(log.command[:, 1] >= -20.0)
    assert sim.saturations() == {}  # the controller clipped before the plant had to
    summary = c.saturation.summary()
    assert summary["limits_N_m"]["elbow"] == [-20.0, 20.0]
    c.reset()
    assert c.saturation.saturated_cycles == 0 and not c.saturation.by_joint()


def test_a_torque_command_on_position_actuators_is_an_error_in_the_simulator(two_link):
    """The 2-link arm with position actuators rejects torque commands, through the simulator."""
    from mbctl.robots.commands import torque

    with pytest.raises(CommandError, match="torque command cannot drive shoulder"):
        Simulator(two_link).send(torque([0.1, 0.2]))


def test_position_target_pd_on_position_actuators(two_link_gravity_pos):
    robot = two_link_gravity_pos
    c = PositionTargetPD(robot)
    sim = Simulator(robot)
    sim.reset(q=[0.2, 0.4])
    log = run(sim, c, joint_reference([0.2, 0.4]), 1.0)
    assert c.compute(sim.read_state(), joint_reference([0.2, 0.4])).kind is CommandKind.POSITION
    np.testing.assert_allclose(log.q[-1], [0.2, 0.4], atol=1e-4)  # gravity offset: no sag


# ------------------------------------------------------------------------------------ loop
def test_loop_validates_and_presamples(two_link_torque):
    sim = Simulator(two_link_torque)
    c = JointPD(two_link_torque, gains_from_frequency(10.0, 1.0, 0.1))
    with pytest.raises(ControlError, match="duration_s"):
        run(sim, c, joint_reference([0.0, 0.0]), 0.0)
    with pytest.raises(ReferenceMismatch):
        run(sim, c, "not a reference", 0.01)  # type: ignore[arg-type]
    t = np.arange(5) * 0.1
    traj = JointTrajectory(t, np.c_[t, 2 * t], np.c_[np.ones(5), 2 * np.ones(5)], np.zeros((5, 2)),
                           ("shoulder", "elbow"))
    q, v, _ = presample(traj, np.array([0.05, 0.15, 1.0]), ("elbow", "shoulder"))
    np.testing.assert_allclose(q, [[0.1, 0.05], [0.3, 0.15], [0.8, 0.4]])
    np.testing.assert_allclose(v[-1], [0.0, 0.0])  # held after the end
    with pytest.raises(ReferenceMismatch, match="not controlled"):
        presample(traj, t, ("elbow",))
    log = run(sim, c, traj, 0.1)
    assert log.cycles == 50 and log.command.shape == (50, 2)
    np.testing.assert_allclose(log.t_s[:3], [0.0, 0.002, 0.004])


def test_task_space_ct_at_a_singularity_raises(two_link_torque):
    from mbctl.control.exceptions import SingularJacobian

    c = TaskSpaceComputedTorque(two_link_torque, gains_from_frequency(10.0))
    sim = Simulator(two_link_torque)
    sim.reset(q=[0.3, 0.0])  # stretched out: det J = l1 l2 sin(q2) = 0
    with pytest.raises(SingularJacobian, match="singular") as info:
        c.compute(sim.read_state(), task_reference([0.5, 0.1]))
    np.testing.assert_allclose(info.value.q, [0.3, 0.0])


def test_loop_rejects_a_reference_of_the_wrong_kind(two_link_torque):
    sim = Simulator(two_link_torque)
    task = TaskSpaceComputedTorque(two_link_torque, gains_from_frequency(10.0))
    with pytest.raises(ReferenceMismatch, match="takes a TaskReference"):
        run(sim, task, joint_reference([0.1, 0.2]), 0.01)
    pd = JointPD(two_link_torque, gains_from_frequency(10.0, 1.0, 0.1))
    with pytest.raises(ReferenceMismatch, match="takes a JointReference"):
        run(sim, pd, task_reference([0.1, 0.2]), 0.01)


def test_a_reference_of_the_wrong_length_is_refused_by_name(two_link_torque):
    """Few joints take the scalar feedback path (no numpy broadcasting to catch a bad length)."""
    from mbctl.robots.interface import RobotState

    state = RobotState(np.zeros(2), np.zeros(2), 0.0)
    for controller in (JointPD(two_link_torque, gains_from_frequency(10.0)),
                       ComputedTorque(two_link_torque, gains_from_frequency(10.0))):
        for bad in (JointReference(np.zeros(3), np.zeros(3), np.zeros(3)),  # one joint too many
                    JointReference(np.zeros(2), np.zeros(1), np.zeros(2))):
            with pytest.raises(ReferenceMismatch, match=r"controls 2 joints \['shoulder', 'elbow'\]"):
                controller.compute(state, bad)


class _UserTorqueLaw(ControllerBase):
    """A user's control law that says nothing about its output: torques, as ControllerBase assumes."""

    name = "user_torque"

    def compute(self, state, reference):  # never reached: construction fails
        raise AssertionError


class _UserVelocityLaw(ControllerBase):
    """A user's control law that outputs velocity targets."""

    name = "user_velocity"
    command_kind = CommandKind.VELOCITY

    def compute(self, state, reference):  # never reached: construction fails
        raise AssertionError


@pytest.mark.parametrize(("law", "build"), [
    ("JointPD", lambda r: JointPD(r, gains_from_frequency(10.0))),
    ("PDGravity", lambda r: PDGravity(r, gains_from_frequency(10.0))),
    ("ComputedTorque", lambda r: ComputedTorque(r, gains_from_frequency(10.0))),
    ("TaskSpaceComputedTorque", lambda r: TaskSpaceComputedTorque(r, gains_from_frequency(10.0))),
    ("_UserTorqueLaw", lambda r: _UserTorqueLaw(r, JointMap.from_robot(r))),
])
def test_torque_laws_on_position_actuators_fail_at_construction(two_link, law, build):
    """Every torque law, in ControllerBase: the simulator's message for the same mistake, said up front."""
    from mbctl.robots.commands import torque

    with pytest.raises(CommandError) as at_step:
        Simulator(two_link).step(torque([0.0, 0.0]))
    with pytest.raises(ControllerSetupError) as at_build:
        build(two_link)
    assert str(at_build.value) == f"{law} outputs torques. {at_step.value}"
    assert "shoulder (position), elbow (position)" in str(at_build.value)
    assert "position_to_motor" in str(at_build.value)


def test_a_law_of_another_kind_is_checked_against_its_own_kind(two_link, two_link_torque):
    from mbctl.robots.commands import velocity_target

    with pytest.raises(CommandError) as at_step:
        Simulator(two_link_torque).send(velocity_target([0.0, 0.0]))
    with pytest.raises(ControllerSetupError) as at_build:
        _UserVelocityLaw(two_link_torque, JointMap.from_robot(two_link_torque))
    assert str(at_build.value) == f"_UserVelocityLaw outputs velocity targets. {at_step.value}"
    assert PositionTargetPD(two_link).command_kind is CommandKind.POSITION  # position targets: accepted
    with pytest.raises(ControllerSetupError, match="PositionTargetPD needs position actuators with kp > 0"):
        PositionTargetPD(two_link_torque)
