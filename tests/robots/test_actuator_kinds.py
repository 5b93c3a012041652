"""Every actuator can be commanded: kinds from gain and bias on any transmission, raw ctrl for all."""

from __future__ import annotations

import numpy as np
import pytest

from mbctl.robots import ctrl, load_robot, position_target, torque
from mbctl.robots.exceptions import CommandError
from mbctl.sim import Simulator

# An arm with a motor, a gripper whose two fingers share a tendon driven by a general
# position-like actuator with a scaled ctrl (as Menagerie's Robotiq 2F-85: 0..255), a velocity
# actuator, and a muscle-like actuator with activation dynamics.
GRIPPER = """<mujoco><option integrator="implicitfast"/><worldbody>
  <body name="arm" pos="0 0 0.5"><joint name="shoulder" axis="0 1 0"/>
    <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="1"/>
    <body name="palm" pos="0.3 0 0"><joint name="wrist" axis="1 0 0"/>
      <geom type="box" size="0.02 0.05 0.02" mass="0.3"/>
      <body name="left" pos="0.03 0.03 0">
          <joint name="left_finger" type="slide" axis="0 1 0" range="0 0.04"/>
        <geom type="box" size="0.01 0.005 0.03" mass="0.05"/></body>
      <body name="right" pos="0.03 -0.03 0">
          <joint name="right_finger" type="slide" axis="0 -1 0" range="0 0.04"/>
        <geom type="box" size="0.01 0.005 0.03" mass="0.05"/></body></body></body>
  </worldbody>
  <tendon><fixed name="split"><joint joint="left_finger" coef="0.5"/>
    <joint joint="right_finger" coef="0.5"/></fixed></tendon>
  <equality><joint joint1="left_finger" joint2="right_finger"/></equality>
  <actuator>
    <motor name="shoulder_motor" joint="shoulder" ctrlrange="-20 20"/>
    <velocity name="wrist_vel" joint="wrist" kv="2"/>
    <general name="fingers" tendon="split" ctrlrange="0 255" gainprm="0.0156863" biastype="affine"
      biasprm="0 -100 -10"/>
    <general name="filtered" joint="wrist" dyntype="filter" dynprm="0.05" gainprm="1"/>
  </actuator></mujoco>"""


@pytest.fixture
def gripper(tmp_path):
    path = tmp_path / "gripper.xml"
    path.write_text(GRIPPER)
    return load_robot(path)


def test_kinds_come_from_gain_and_bias_on_any_transmission(gripper):
    kinds = {a.name: (a.kind, a.transmission) for a in gripper.actuators.values()}
    assert kinds == {
        "shoulder_motor": ("torque", "joint shoulder"),
        "wrist_vel": ("velocity", "joint wrist"),
        "fingers": ("position", "tendon split"),
        "filtered": ("other", "joint wrist"),
    }
    fingers = gripper.actuator("fingers")
    assert fingers.kp == 100 and fingers.kv == 10
    assert fingers.target_per_ctrl == pytest.approx(0.0156863 / 100)  # ctrl 255 -> 0.04 m of tendon


def test_tendon_position_actuator_takes_a_position_target_by_name(gripper):
    sim = Simulator(gripper)
    sim.step(position_target({"fingers": 255.0}), n=1500)
    # the tendon length (mean finger opening) settles at the scaled target, 255 * 0.0156863 / 100 m
    opening = np.mean([sim.joint_q("left_finger")[0], sim.joint_q("right_finger")[0]])
    assert opening == pytest.approx(0.04, abs=2e-3)
    with pytest.raises(CommandError, match=r"A torque command cannot drive fingers \(position\)"):
        sim.send(torque({"fingers": 1.0}))


def test_a_full_ctrl_vector_drives_every_actuator_kind(gripper):
    sim = Simulator(gripper)
    sim.send(ctrl([1.0, 0.5, 100.0, 0.2]))
    np.testing.assert_array_equal(sim.data.ctrl, [1.0, 0.5, 100.0, 0.2])
    with pytest.raises(CommandError, match=r"torque command cannot drive wrist_vel \(velocity\), fingers "
                                           r"\(position\), filtered \(other\).*raw ctrl command"):
        sim.send(torque([1.0, 0.5, 100.0, 0.2]))
    with pytest.raises(CommandError, match="needs 4 values"):
        sim.send(ctrl([1.0]))
