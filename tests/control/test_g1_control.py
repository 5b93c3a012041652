"""G1 control: base weld (engines agree on M and bias), controller setup errors, command kinds.

The G1 jobs (standing, welded-base tracking, arm PD) are tested in tests/jobs/test_g1_jobs.py."""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from mbctl.control.computed_torque import ComputedTorque
from mbctl.control.controller import JointMap, joint_reference
from mbctl.control.exceptions import ControllerSetupError
from mbctl.control.gains import gains_from_frequency
from mbctl.control.pd_gravity import PDGravity
from mbctl.robots.commands import CommandKind
from mbctl.robots.edits import position_to_motor, weld_base
from mbctl.robots.exceptions import CommandError, RobotError
from mbctl.sim.simulator import Simulator


@pytest.fixture(scope="module")
def g1_welded(g1):
    return weld_base(g1, "stand")


def test_weld_base_engines_agree_on_mass_matrix_and_bias(g1_welded, g1):
    robot = g1_welded
    assert not robot.has_floating_base
    assert (robot.nq, robot.nv, robot.nu) == (g1.nq - 7, g1.nv - 6, g1.nu)
    assert "floating_base_joint" not in robot.joints
    assert robot.mj_model.key_qpos.shape == (len(robot.keyframes), robot.nq)
    m, d = robot.mj_model, mujoco.MjData(robot.mj_model)
    pdata = robot.pin_model.createData()
    rng = np.random.default_rng(3)
    lo, hi = m.jnt_range[:, 0], m.jnt_range[:, 1]
    for _ in range(3):
        q = rng.uniform(lo, hi)
        v = rng.uniform(-1.0, 1.0, robot.nv)
        d.qpos[:], d.qvel[:] = q, v
        mujoco.mj_forward(m, d)
        M_mj = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, d, M_mj)
        M_pin = pin.crba(robot.pin_model, pdata, q)
        np.testing.assert_allclose(M_pin, M_mj, atol=1e-10)
        np.testing.assert_allclose(pin.nonLinearEffects(robot.pin_model, pdata, q, v), d.qfrc_bias,
                                   atol=1e-9)
    # the pelvis sits at the keyframe pose in both engines
    d.qpos[:] = robot.keyframe_q("stand")
    mujoco.mj_kinematics(m, d)
    key = g1.mj_model.key_qpos[g1.keyframe_id("stand")]
    np.testing.assert_allclose(d.xpos[robot.body_id("pelvis")], key[:3])
    assert any("welded" in e for e in robot.source.edits)


def test_weld_base_needs_a_floating_base(two_link_torque):
    with pytest.raises(RobotError, match="no floating base"):
        weld_base(two_link_torque)


def test_floating_base_setup_errors(g1):
    motors = position_to_motor(g1)
    with pytest.raises(ControllerSetupError, match="every dof"):
        ComputedTorque(motors, gains_from_frequency(10.0))
    with pytest.raises(ControllerSetupError, match="free joint"):
        JointMap.from_robot(motors, ["floating_base_joint"])
    jm = JointMap.from_robot(motors)
    assert jm.size == 29 and jm.idx_v.min() == 6  # actuated joints only, base dofs excluded


def test_torque_controller_on_menagerie_position_actuators_is_an_error(g1):
    """At construction, with the simulator's message; after position_to_motor the same law builds."""
    from mbctl.robots.commands import torque

    with pytest.raises(CommandError) as at_step:
        Simulator(g1).send(torque(np.zeros(g1.nu)))
    with pytest.raises(ControllerSetupError) as at_build:
        PDGravity(g1, gains_from_frequency(10.0, 1.0, 0.1))
    assert str(at_build.value) == f"PDGravity outputs torques. {at_step.value}"
    assert "position_to_motor" in str(at_build.value)
    motors = position_to_motor(g1)
    assert PDGravity(motors, gains_from_frequency(10.0, 1.0, 0.1)).joints[0] == "left_hip_pitch_joint"


def test_position_target_pd_commands_position_actuators(g1):
    sim = Simulator(g1)
    sim.reset("stand")  # ctrl holds the keyframe's targets
    from mbctl.control.position_pd import PositionTargetPD

    c = PositionTargetPD(g1, ["left_elbow_joint"])
    reference = joint_reference([0.5])
    cmd = c.compute(sim.read_state(), reference)
    assert cmd.kind is CommandKind.POSITION and cmd.names == ("left_elbow_joint",)
    # target = q_ref + g(q)/kp: a gravity offset of under 1 mrad at kp = 500 N m/rad
    assert cmd.values[0] == pytest.approx(0.5, abs=1e-3) and cmd.values[0] != 0.5
    ctrl_before = sim.ctrl.copy()
    sim.send(cmd)
    elbow = g1.actuator_for_joint("left_elbow_joint").index
    assert np.flatnonzero(sim.ctrl != ctrl_before).tolist() == [elbow]  # only the elbow's target
    assert sim.ctrl[elbow] == cmd.values[0]
    # and the position actuator takes the elbow there (from 1.28 rad in the keyframe)
    assert abs(sim.joint_q("left_elbow_joint")[0] - 0.5) > 0.5
    for _ in range(round(1.0 / sim.control_period_s)):
        sim.send(c.compute(sim.read_state(), reference))
        sim.sync()
    assert abs(sim.joint_q("left_elbow_joint")[0] - 0.5) < 1e-4
    assert sim.warnings == {}
