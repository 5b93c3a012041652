"""The MuJoCo backend: stepping, typed commands, state in Pinocchio's convention, divergence."""

from __future__ import annotations

import time

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from mbctl.control import JointPD, gains_from_frequency, joint_reference, run
from mbctl.robots import StateError, UnknownNameError, load_robot
from mbctl.robots.exceptions import CommandError, CommandOutOfRange
from mbctl.sim import (
    SimError,
    SimulationDiverged,
    Simulator,
    position_target,
    torque,
    velocity_target,
)


def test_two_link_setup_figures(two_link):
    sim = Simulator(two_link)
    q0 = sim.q
    sim.step(position_target([5.0, -3.0]), 100)
    assert sim.time_s == pytest.approx(0.2, abs=1e-12)
    assert sim.n_steps == 100
    assert np.all(np.abs(sim.q - q0) > 0.5)


def test_read_state_is_a_whole_robot_state(two_link_torque):
    """read_state builds its RobotState without the namedtuple's __new__ (per cycle): every field
    must be given. A 3-item tuple made ``repr`` raise TypeError and ``.estimated`` IndexError."""
    sim = Simulator(two_link_torque)
    sim.step(torque([0.1, -0.1]), 7)
    state = sim.read_state()
    assert len(state) == len(type(state)._fields) == 5
    assert repr(state).startswith("RobotState(q=array(") and "tick=7" in repr(state)
    assert state.estimated == () and state.tick == sim.n_steps == 7
    assert state.time_s == pytest.approx(7 * two_link_torque.mj_model.opt.timestep, abs=1e-15)
    assert state == type(state)(state.q, state.v, state.time_s, (), 7)


def test_simulator_runs_the_control_loop_as_a_robot_interface(two_link_torque):
    """control.loop.run drives the simulator through read_state / send / sync only."""
    sim = Simulator(two_link_torque, control_period_s=0.004)
    q_ref = np.array([0.4, -0.3])
    controller = JointPD(two_link_torque, gains_from_frequency(20.0, 1.0, 0.05))
    log = run(sim, controller, joint_reference(q_ref), 0.2)
    assert log.cycles == 50
    # one sync per cycle, each two physics steps; the log holds the state read before each command
    assert sim.n_steps == 100 and sim.time_s == pytest.approx(0.2, abs=1e-12)
    np.testing.assert_allclose(log.t_s, 0.004 * np.arange(50), atol=1e-12)
    np.testing.assert_array_equal(log.q[0], [0.0, 0.0])
    # the commands the loop sent are the PD law on the state it read, and they reached ctrl
    np.testing.assert_allclose(
        log.command, controller.gains.kp * (q_ref - log.q) - controller.gains.kd * log.v, atol=1e-12
    )
    np.testing.assert_allclose(sim.ctrl, log.command[-1], atol=0)
    # the state advances toward the reference: the joints move and the error shrinks
    assert np.all(np.abs(np.diff(log.q[:, 0])) > 0)
    assert np.abs(sim.q - q_ref).max() < 0.2 * np.abs(q_ref).max()


def test_state_read_fast_path_equals_the_reference_conversion_g1(g1):
    """read_state / q / v (scalar free-flyer rotation) against StateConverter.q_mj_to_pin and
    v_mj_to_pin (3x3 matrix) and against Pinocchio's own quaternion, at random raw states.

    The quaternions are random and not normalized (read_state reads qpos as MuJoCo holds it),
    the velocities up to ~10 m/s; agreement is to a few ulp of |v| (Pinocchio's rounding
    differs by up to ~4.5 ulp over 2000 states, so it gets twice the tolerance).
    """
    sim = Simulator(g1)
    conv = g1.converter
    rng = np.random.default_rng(11)
    for _ in range(50):
        qpos = rng.uniform(-1.0, 1.0, g1.nq)
        qpos[3:7] = rng.normal(size=4) * rng.uniform(0.5, 2.0)  # (w, x, y, z), any norm
        qvel = rng.normal(scale=3.0, size=g1.nv)
        sim.data.qpos[:], sim.data.qvel[:] = qpos, qvel
        state = sim.read_state()
        q_ref = conv.q_mj_to_pin(qpos)
        v_ref = conv.v_mj_to_pin(q_ref, qvel)
        tol = 1e-15 * np.abs(qvel[:3]).max()  # ~4 ulp
        np.testing.assert_array_equal(state.q, q_ref)  # a permutation: exact
        np.testing.assert_allclose(state.v, v_ref, rtol=0, atol=tol)
        np.testing.assert_array_equal(state.v[3:], qvel[3:])  # only the base linear part turns
        w, x, y, z = qpos[3:7]
        R_WB = pin.Quaternion(w, x, y, z).normalized().toRotationMatrix()
        np.testing.assert_allclose(state.v[:3], R_WB.T @ qvel[:3], rtol=0, atol=2 * tol)  # Eigen
        np.testing.assert_array_equal(state.q[3:7], [x, y, z, w])
        # the properties read the same fast path; reading does not step or write the state
        np.testing.assert_array_equal(sim.q, state.q)
        np.testing.assert_array_equal(sim.v, state.v)
        np.testing.assert_array_equal(sim.data.qpos, qpos)
        np.testing.assert_array_equal(sim.data.qvel, qvel)
        assert state.time_s == sim.time_s
    # at a zero quaternion the rotation is undefined: a StateError, not a ZeroDivisionError
    sim.data.qpos[3:7] = 0.0
    with pytest.raises(StateError, match="zero norm"):
        sim.read_state()


def test_derived_quantities_follow_the_new_state(two_link_torque):
    """After a step, site poses and sensors correspond to the new q (mj_forward), matching
    Pinocchio's forward kinematics at that q."""
    robot = two_link_torque
    sim = Simulator(robot)
    sim.step(torque([2.0, -1.0]), 50)
    pm = robot.pin_model
    pd = pm.createData()
    pin.framesForwardKinematics(pm, pd, sim.q)
    p_pin = pd.oMf[robot.frame_id("end_effector")].translation
    p_sim, R_sim = sim.site_pose("end_effector")
    np.testing.assert_allclose(p_sim, p_pin, atol=1e-12)
    np.testing.assert_allclose(sim.sensor("ee_pos"), p_pin, atol=1e-12)
    np.testing.assert_allclose(R_sim, pd.oMf[robot.frame_id("end_effector")].rotation, atol=1e-12)


def test_sensor_and_state_are_copies(two_link_torque):
    sim = Simulator(two_link_torque)
    state = sim.read_state()
    reading = sim.sensor("ee_pos")
    sim.step(torque([3.0, 3.0]), 20)
    assert state.q.flags.writeable is False
    np.testing.assert_array_equal(state.q, 0.0)
    assert not np.allclose(sim.sensor("ee_pos"), reading)
    reading[:] = 99
    assert not np.any(sim.sensor("ee_pos") == 99)


def test_torque_to_position_actuator_is_an_error(two_link):
    sim = Simulator(two_link)
    with pytest.raises(CommandError, match=r"A torque command cannot drive shoulder \(position\)"):
        sim.step(torque([1.0, 0.0]))
    with pytest.raises(CommandError, match=r"velocity command cannot drive"):
        sim.send(velocity_target({"elbow": 1.0}))


@pytest.mark.parametrize(
    "make, error, message",
    [
        (lambda: position_target([1.0, 2.0, 3.0]), CommandError, "needs 2 values .* got 3"),
        (lambda: position_target({"elbw": 1.0}), UnknownNameError, "Did you mean 'elbow'"),
        (lambda: position_target([np.nan, 0.0]), CommandError, r"finite; got \[nan\] at \[0\]"),
        (lambda: position_target({"elbow": np.inf}), CommandError, r"at \['elbow'\]"),
        (lambda: position_target("x"), CommandError, "values must be numbers"),
    ],
)
def test_bad_commands_are_named(two_link, make, error, message):
    sim = Simulator(two_link)
    with pytest.raises(error, match=message):
        sim.send(make())


def test_partial_command_by_joint_name_holds_the_rest(two_link):
    sim = Simulator(two_link)
    sim.send(position_target([0.5, -0.5]))
    sim.send(position_target({"elbow": 1.0}))  # joint name == actuator name here
    np.testing.assert_array_equal(sim.ctrl, [0.5, 1.0])


# Motors named apart from their joints, so one actuator has two names: "m_shoulder" and "shoulder".
RENAMED_MOTORS_XML = """<mujoco><worldbody><body name="upper">
  <joint name="shoulder" axis="0 0 1"/><geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
  <body name="fore" pos="0.3 0 0"><joint name="elbow" axis="0 0 1"/>
    <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/></body></body></worldbody>
  <actuator><motor name="m_shoulder" joint="shoulder"/><motor name="m_elbow" joint="elbow"/></actuator>
</mujoco>"""


@pytest.mark.parametrize(
    "values, message",
    [
        ({"shoulder": 0.3, "m_shoulder": 0.7},
         r"names actuator 'm_shoulder' twice: as 'shoulder' \(its joint\) and as 'm_shoulder'"),
        ({"m_elbow": 0.1, "elbow": 0.2},
         r"names actuator 'm_elbow' twice: as 'm_elbow' and as 'elbow' \(its joint\)"),
    ],
)
def test_one_actuator_named_twice_is_an_error(tmp_path, values, message):
    path = tmp_path / "arm.xml"
    path.write_text(RENAMED_MOTORS_XML)
    sim = Simulator(load_robot(path))
    with pytest.raises(CommandError, match=message):
        sim.send(torque(values))
    np.testing.assert_array_equal(sim.ctrl, [0.0, 0.0])  # nothing was written
    sim.send(torque({"shoulder": 0.3, "m_elbow": 0.7}))  # a joint name and another actuator's name
    np.testing.assert_array_equal(sim.ctrl, [0.3, 0.7])


def test_out_of_range_is_clamped_and_counted(two_link_torque):
    sim = Simulator(two_link_torque)
    sim.step(torque([100.0, -5.0]), 3)
    np.testing.assert_array_equal(sim.ctrl, [30.0, -5.0])
    assert sim.saturations() == {"shoulder": 1}
    sim.step(torque([31.0, -25.0]))
    assert sim.saturations() == {"shoulder": 2, "elbow": 1}


def test_out_of_range_can_raise(two_link_torque):
    sim = Simulator(two_link_torque, out_of_range="raise")
    with pytest.raises(CommandOutOfRange, match=r"40 for actuator 'shoulder' is outside .*\[-30, 30\]"):
        sim.send(torque([40.0, 0.0]))


def test_control_period_must_divide(two_link):
    with pytest.raises(SimError, match="integer multiple of the timestep 0.002"):
        Simulator(two_link, control_period_s=0.003)
    sim = Simulator(two_link, control_period_s=0.01)
    assert sim.n_substeps == 5 and sim.physics_time_s == 0.0
    t0 = time.perf_counter()
    sim.sync()
    assert sim.time_s == pytest.approx(0.01)
    assert 0.0 < sim.physics_time_s < time.perf_counter() - t0  # the five steps' wall time, timed


def test_divergence_raises_with_the_warning_name(tmp_path):
    xml = """<mujoco><worldbody><body name="b"><joint name="j" type="slide" axis="1 0 0"/>
    <geom size="0.1" mass="1"/></body></worldbody>
    <actuator><motor name="m" joint="j"/></actuator></mujoco>"""
    (tmp_path / "slider.xml").write_text(xml)
    sim = Simulator(load_robot(tmp_path / "slider.xml"))
    sim.set_state([0.0], [1e11])  # beyond MuJoCo's mjMAXVAL: it resets the state silently
    with pytest.raises(SimulationDiverged, match=r"BADQVEL \(x1\)") as info:
        sim.step(None, 2)
    assert info.value.warnings == {"BADQVEL": 1}
    assert sim.q[0] == 0.0  # MuJoCo reset the state, which is why we raise
    with pytest.raises(SimulationDiverged, match="BADCTRL"):
        sim.step(torque([1e300]))


def test_reset_to_keyframe_g1(g1):
    sim = Simulator(g1)
    sim.reset("stand")
    np.testing.assert_array_equal(sim.q[3:7], [0, 0, 0, 1])
    assert sim.base_z_m == pytest.approx(0.79)
    np.testing.assert_array_equal(sim.ctrl, g1.keyframe_ctrl("stand"))
    with pytest.raises(UnknownNameError, match="Did you mean 'stand'"):
        sim.reset("stnd")


def test_g1_velocity_is_pinocchio_convention(g1):
    """A base rotated 90 deg about z moving along its own x moves along world y in MuJoCo."""
    sim = Simulator(g1)
    q = g1.keyframe_q("stand")
    q[3:7] = [0, 0, np.sin(np.pi / 4), np.cos(np.pi / 4)]
    v = np.zeros(g1.nv)
    v[0] = 1.0
    sim.set_state(q, v)
    np.testing.assert_allclose(sim.data.qvel[:3], [0, 1, 0], atol=1e-15)
    np.testing.assert_allclose(sim.v[:3], [1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(sim.data.qpos[3:7], [np.cos(np.pi / 4), 0, 0, np.sin(np.pi / 4)])
    with pytest.raises(StateError, match=r"v must have shape \(35,\)"):
        sim.set_state(q, np.zeros(36))


def test_g1_holds_stand_with_position_actuators(g1):
    sim = Simulator(g1)
    sim.reset("stand")
    sim.step(position_target(g1.keyframe_ctrl("stand")), 500)
    assert abs(sim.base_z_m - 0.79) < 0.02
    assert sim.contact_count > 0
    assert sim.warnings == {}
    # the body pose agrees with the free joint
    p, _ = sim.body_pose("pelvis")
    np.testing.assert_allclose(p, sim.q[:3], atol=1e-12)
    assert mujoco.mj_name2id(g1.mj_model, mujoco.mjtObj.mjOBJ_BODY, "pelvis") == g1.body_id("pelvis")


def test_observers_run_after_each_step_and_can_be_removed():
    from mbctl.robots import load_robot
    from mbctl.sim.simulator import Simulator

    sim = Simulator(load_robot("two_link_torque"))
    seen: list[float] = []

    def obs(s: Simulator) -> None:
        seen.append(s.time_s)

    sim.add_observer(obs)
    sim.step(n=3)
    sim.step()
    assert len(seen) == 2 and seen[-1] == pytest.approx(4 * sim.model.opt.timestep)
    sim.remove_observer(obs)
    sim.step()
    assert len(seen) == 2


def test_hold_lets_time_pass_with_the_state_still(two_link_torque_gravity):
    sim = Simulator(two_link_torque_gravity)
    sim.set_state([0.3, -0.2], [0.0, 0.0])
    seen = []
    sim.add_observer(lambda s: seen.append(s.time_s))
    q0 = sim.q
    sim.hold()
    sim.hold(3)
    assert np.array_equal(sim.q, q0) and sim.n_steps == 0
    assert seen == pytest.approx([0.002, 0.008])
    sim.step()
    assert not np.array_equal(sim.q, q0)  # gravity: uncommanded, it moves once stepped
    with pytest.raises(SimError, match="positive number of steps; got 0"):
        sim.hold(0)


def test_divergence_names_when_it_happened_not_mujocos_restarted_clock(tmp_path):
    """MuJoCo resets a diverged state, its time included: the error gives the time before the steps."""
    xml = """<mujoco><worldbody><body name="b"><joint name="j" type="slide" axis="1 0 0"/>
    <geom size="0.1" mass="1"/></body></worldbody>
    <actuator><motor name="m" joint="j"/></actuator></mujoco>"""
    (tmp_path / "slider.xml").write_text(xml)
    sim = Simulator(load_robot(tmp_path / "slider.xml"))
    for _ in range(10):
        sim.sync()
    sim.set_state([0.0], [1e11])
    with pytest.raises(SimulationDiverged, match=r"near t=0\.0200 s") as info:
        sim.sync()
    assert info.value.time_s == pytest.approx(0.02) and sim.time_s < 0.01  # MuJoCo's clock restarted
