"""Robot and scene: the robot is the trees the actuators drive; the rest of the plant is scene.

The model here puts every kind of scene body before the robot (a free box whose 7 coordinates
come first in qpos, a static wall with mass, a mocap target with a site), so the robot's q and v
map into the plant's qpos and qvel at an offset.
"""

from __future__ import annotations

import re
import subprocess
import sys

import mujoco
import numpy as np
import pytest

from mbctl.robots import UnknownNameError, load_robot
from mbctl.robots.commands import torque
from mbctl.robots.crosscheck import crosscheck
from mbctl.sim import Simulator

SCENE = """<mujoco>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    <body name="box" pos="0.5 0.3 0.5"><freejoint name="box_free"/>
      <geom type="box" size="0.05 0.05 0.05" mass="0.4"/></body>
    <body name="wall" pos="1 0 0.5"><geom type="box" size="0.05 1 0.5" mass="50"/></body>
    <body name="target" mocap="true" pos="0.3 0 0.4"><site name="target_site"/>
      <geom type="sphere" size="0.02" contype="0" conaffinity="0" mass="0.1"/></body>
    <body name="mount" pos="0 0 0.3" euler="20 0 30">
      <geom type="cylinder" size="0.05 0.05" mass="3"/>
      <body name="upper" pos="0 0 0.1">
        <joint name="shoulder" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="1.2"/>
        <body name="fore" pos="0.3 0 0">
          <joint name="elbow" axis="0 1 0"/>
          <geom type="box" size="0.12 0.02 0.02" pos="0.12 0 0.01" mass="0.7"/>
          <site name="tool" pos="0.25 0 0"/></body></body></body>
  </worldbody>
  <actuator><motor name="m_shoulder" joint="shoulder"/><motor name="m_elbow" joint="elbow"/></actuator>
  <keyframe><key name="home" qpos="0.5 0.3 0.5 1 0 0 0 0.3 -0.7"/></keyframe>
</mujoco>"""


@pytest.fixture
def scene_file(tmp_path):
    path = tmp_path / "arm_scene.xml"
    path.write_text(SCENE)
    return path


def test_robot_is_the_actuated_tree_and_maps_into_the_plant(scene_file):
    robot = load_robot(scene_file)
    assert list(robot.joints) == ["shoulder", "elbow"]
    assert (robot.nq, robot.nv, robot.mj_model.nq, robot.mj_model.nv) == (2, 2, 9, 8)
    assert not robot.covers_plant
    assert robot.joint("shoulder").idx_q == 0 and robot.joint("shoulder").qposadr == 7
    assert robot.qpos_index == slice(7, 9) and robot.qvel_index == slice(6, 8)
    assert robot.bodies == ("mount", "upper", "fore") and robot.sites == ("tool",)
    assert robot.scene_bodies == ("box (free, 0.4 kg)", "wall (static, 50 kg)", "target (mocap, 0.1 kg)")
    assert robot.site_id("target_site") == 0  # scene sites and bodies can still be looked up
    assert robot.body_id("box") == 1
    np.testing.assert_allclose(robot.keyframe_q("home"), [0.3, -0.7])
    assert sum(i.mass for i in robot.pin_model.inertias) == pytest.approx(4.9, rel=1e-12)


def test_cross_check_compares_the_robot_at_round_off(scene_file):
    report = crosscheck(load_robot(scene_file), n_states=40, seed=2)
    assert report.passed, report.to_text()
    assert max(q.max_rel_error for q in report.quantities) < 1e-9
    scene = next(f for f in report.features if f.feature == "scene bodies")
    assert "box (free, 0.4 kg), wall (static, 50 kg), target (mocap, 0.1 kg)" in scene.detail
    assert "multiple" not in report.to_text()  # no "several trees" hint for scene bodies


def test_simulator_reads_and_writes_only_the_robot(scene_file):
    robot = load_robot(scene_file)
    sim = Simulator(robot)
    box_q0 = sim.data.qpos[:7].copy()
    sim.set_state([0.2, -0.4], [0.1, 0.0])
    np.testing.assert_array_equal(sim.data.qpos[:7], box_q0)  # the box is not written
    np.testing.assert_allclose(sim.data.qpos[7:], [0.2, -0.4])
    np.testing.assert_allclose(sim.data.qvel[6:], [0.1, 0.0])
    np.testing.assert_allclose(sim.q, [0.2, -0.4])
    sim.step(torque([0.0, 0.0]), n=100)  # a full-vector command on the robot's actuators
    assert sim.state.q.shape == (2,) and sim.state.v.shape == (2,)
    assert sim.data.qpos[2] < box_q0[2] - 0.05  # the plant still steps the scene: the box falls
    np.testing.assert_allclose(sim.body_pose("target")[0], [0.3, 0.0, 0.4])  # mocap stays put
    # the plant's tool position equals Pinocchio's at the robot's q
    p_mj = sim.site_pose("tool")[0]
    p_pin = robot.frame_pose("tool", sim.q)[0]
    np.testing.assert_allclose(p_pin, p_mj, atol=1e-12)


def test_root_selects_the_robot_and_unknown_roots_are_named(scene_file):
    box = load_robot(scene_file, roots=("box",))  # a user may call the free box the robot
    assert list(box.joints) == ["box_free"] and box.has_floating_base and box.nq == 7
    assert crosscheck(box, n_states=10).passed
    both = load_robot(scene_file, roots=("box", "fore"))  # "fore" selects the arm's whole tree
    assert list(both.joints) == ["box_free", "shoulder", "elbow"] and both.covers_plant
    with pytest.raises(UnknownNameError, match="root body 'forearm'"):
        load_robot(scene_file, roots=("forearm",))


def test_inspect_lists_the_scene_and_equal_masses_print_once(scene_file):
    out = subprocess.run([sys.executable, "-m", "mbctl.cli", "inspect", str(scene_file)],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert re.search(r"\nmass \(kg\) +4\.9000 +4\.9000\n", out.stdout), out.stdout
    assert "scene (in the plant, not the robot; plant nq 9, nv 8, 55.4000 kg in all):" in out.stdout
    assert "  box (free, 0.4 kg)\n  wall (static, 50 kg)\n  target (mocap, 0.1 kg)" in out.stdout
    out = subprocess.run([sys.executable, "-m", "mbctl.cli", "inspect", str(scene_file), "--root", "box"],
                         capture_output=True, text=True, timeout=60)
    assert "\n  box_free " in out.stdout and "\n  shoulder " not in out.stdout
    assert "  upper (jointed, 1.2 kg)\n  fore (jointed, 0.7 kg)" in out.stdout


def test_robot_from_an_include_with_a_scene_cross_checks_and_ik_lands(tmp_path):
    robot_xml = SCENE.split("<worldbody>")[1].split("</worldbody>")[0]
    robot_xml = robot_xml[robot_xml.index('<body name="mount"'):]
    (tmp_path / "arm.xml").write_text(
        f'<mujoco model="arm"><worldbody>{robot_xml}</worldbody><actuator>'
        '<motor joint="shoulder"/><motor joint="elbow"/></actuator></mujoco>')
    (tmp_path / "scene.xml").write_text(
        '<mujoco><include file="arm.xml"/><worldbody><geom type="plane" size="1 1 .1"/>'
        '<body name="ball" pos="0.4 0 1"><freejoint/><geom type="sphere" size="0.03" mass="0.1"/>'
        '</body></worldbody></mujoco>')
    robot = load_robot(tmp_path / "arm.xml", tmp_path / "scene.xml")
    assert list(robot.joints) == ["shoulder", "elbow"] and robot.mj_model.nq == 9
    assert crosscheck(robot, n_states=20).passed
    m, d = robot.mj_model, mujoco.MjData(robot.mj_model)
    robot.plant_qpos([0.5, -0.8], d.qpos)
    mujoco.mj_kinematics(m, d)
    target = ",".join(f"{x:.6f}" for x in d.site_xpos[robot.site_id("tool")])
    out = subprocess.run(
        [sys.executable, "-m", "mbctl.cli", "ik", str(tmp_path / "arm.xml"), "--scene",
         str(tmp_path / "scene.xml"), "--target", f"tool={target}", "--output", str(tmp_path / "ik"),
         "--quiet"], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "plant check: largest residual in MuJoCo" in out.stdout


def test_scene_for_a_known_robot_is_used_not_ignored(tmp_path):
    from mbctl.robots.registry import KNOWN_ROBOTS

    robot_file, _, _ = KNOWN_ROBOTS["two_link_torque"].locate(None)
    scene = tmp_path / "scene.xml"
    scene.write_text(f'<mujoco><include file="{robot_file}"/><worldbody><body name="prop" pos="0 0 1">'
                     '<freejoint name="prop_free"/>'
                     '<inertial pos="0 0 0" mass="2" diaginertia="0.01 0.01 0.01"/>'
                     '</body></worldbody><actuator><motor joint="shoulder"/><motor joint="elbow"/></actuator>'
                     '</mujoco>')
    robot = load_robot("two_link_torque", scene)
    assert robot.source.scene_file == scene.resolve() and robot.mj_model.nq == robot.nq + 7
    assert "scene" in robot.source.origin
    # a passive scene (no actuators): the robot file's trees are the robot, the prop stays scene
    scene.write_text(scene.read_text().replace('<actuator><motor joint="shoulder"/><motor joint="elbow"/>'
                                               '</actuator>', ""))
    passive = load_robot("two_link", scene)
    assert list(passive.joints) == ["shoulder", "elbow"] and passive.source.roots == ("link1",)
    assert passive.scene_bodies == ("prop (free, 2 kg)",)
    # the same file loaded as the robot (no robot file beside it): every tree with a joint
    alone = load_robot(scene)
    assert alone.covers_plant and list(alone.joints)[-1] == "prop_free"
