"""Loading the model pair: known robots, user files, Menagerie resolution, agreement checks."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from mbctl.robots import (
    ModelFileError,
    ModelMismatchError,
    ModelNotFoundError,
    UnknownNameError,
    load_robot,
)
from mbctl.robots.edits import position_to_motor
from mbctl.robots.menagerie import verify_manifest
from mbctl.robots.registry import ASSETS

ARM_XML = (ASSETS / "two_link_arm.xml").read_text()


def test_two_link_description(two_link, two_link_torque):
    for robot in (two_link, two_link_torque):
        assert (robot.nq, robot.nv, robot.nu) == (2, 2, 2)
        assert list(robot.joints) == ["shoulder", "elbow"]
        assert robot.timestep_s == 0.002
        np.testing.assert_array_equal(robot.mj_model.opt.gravity, 0.0)
        np.testing.assert_array_equal(robot.pin_model.gravity.linear, 0.0)
        masses = [robot.pin_model.inertias[i].mass for i in range(1, 3)]
        np.testing.assert_allclose(masses, [1.0, 0.7 + 0.05])  # ee body is fixed to link 2
    assert {a.kind for a in two_link.actuators.values()} == {"position"}
    assert {a.kind for a in two_link_torque.actuators.values()} == {"torque"}
    # end effector 0.3 + 0.3 + 0.015 m along x at q = 0, in both engines
    pm = two_link.pin_model
    pd = pm.createData()
    pin.framesForwardKinematics(pm, pd, np.zeros(2))
    np.testing.assert_allclose(pd.oMf[two_link.frame_id("end_effector")].translation, [0.615, 0, 0])


def test_gravity_switch_is_in_the_arm_plane(two_link_torque_gravity):
    r = two_link_torque_gravity
    np.testing.assert_array_equal(r.mj_model.opt.gravity, [0, -9.81, 0])
    np.testing.assert_array_equal(r.pin_model.gravity.linear, [0, -9.81, 0])
    assert "gravity set to (0.0, -9.81, 0.0) m/s^2" in r.source.edits
    g = pin.computeGeneralizedGravity(r.pin_model, r.pin_model.createData(), np.zeros(2))
    assert np.all(np.abs(g) > 0.1)  # horizontal arm under -y gravity needs holding torque


def test_g1_model_pair(g1):
    assert (g1.nq, g1.nv, g1.nu) == (36, 35, 29)
    assert g1.has_floating_base
    assert all(a.kind == "position" for a in g1.actuators.values())
    q = g1.keyframe_q("stand")
    np.testing.assert_array_equal(q[3:7], [0, 0, 0, 1])  # Pinocchio (x, y, z, w)
    assert g1.joint("left_elbow_joint").q_slice == slice(25, 26)
    assert q[25] == 1.28  # the stand keyframe bends the elbow
    assert g1.sensor("imu-pelvis-angular-velocity").dim == 3
    knee = g1.actuator("left_knee_joint")
    assert knee.force_range == (-139.0, 139.0) and knee.kp == 500.0


@pytest.mark.parametrize(
    "lookup, kind",
    [("joint", "joint"), ("actuator", "actuator"), ("sensor", "sensor"), ("keyframe_id", "keyframe")],
)
def test_unknown_names_suggest_close_matches(g1, lookup, kind):
    with pytest.raises(UnknownNameError, match=rf"Unknown {kind} 'left_elbw_joint'") as info:
        getattr(g1, lookup)("left_elbw_joint")
    if kind in ("joint", "actuator"):
        assert info.value.suggestions[0] == "left_elbow_joint"


def test_unknown_robot_name():
    with pytest.raises(UnknownNameError, match="Did you mean 'two_link'"):
        load_robot("two_lnk")


def test_user_file_by_path(tmp_path):
    (tmp_path / "arm.xml").write_text(ARM_XML)
    robot = load_robot(tmp_path / "arm.xml")
    assert robot.name == "arm" and robot.nu == 0 and robot.nq == 2


def test_corrupted_model_file_is_named(tmp_path):
    bad = tmp_path / "broken.xml"
    bad.write_text(ARM_XML[: len(ARM_XML) // 2])
    with pytest.raises(ModelFileError, match="broken.xml"):
        load_robot(bad)


@pytest.mark.parametrize(
    "old, new, message",
    [
        ('mass="0.7"', 'mass="0.707"', "robot mass differs"),
        ('armature="0.002"', 'armature="0.0"', "armature differs at dofs"),
        ('<joint name="elbow"/>', '<joint name="knee"/>', "joint names/order differ"),
    ],
)
def test_agreement_check_names_the_difference(tmp_path, old, new, message):
    edited = tmp_path / "pin_side.xml"
    edited.write_text(ARM_XML.replace(old, new))
    with pytest.raises(ModelMismatchError, match=message):
        load_robot("two_link", pin_model_file=edited)


def test_menagerie_root_without_model(tmp_path, monkeypatch):
    monkeypatch.setenv("MENAGERIE_ROOT", str(tmp_path))
    with pytest.raises(ModelNotFoundError, match="MENAGERIE_ROOT=.* has no 'unitree_g1' folder"):
        load_robot("g1")


def test_offline_package_says_how_to_set_menagerie_root(monkeypatch):
    import mujoco_menagerie

    def offline(*args, **kwargs):
        raise mujoco_menagerie.DownloadError("network unreachable")

    monkeypatch.delenv("MENAGERIE_ROOT", raising=False)
    monkeypatch.setattr(mujoco_menagerie.Robot, "path", offline)
    with pytest.raises(ModelNotFoundError, match="Set MENAGERIE_ROOT"):
        load_robot("g1")


def test_manifest_catches_a_modified_file(g1, tmp_path):
    copy = tmp_path / "unitree_g1"
    shutil.copytree(Path(g1.source.robot_file).parent, copy)
    verify_manifest(copy)  # intact copy passes
    with open(copy / "g1.xml", "a") as f:
        f.write("<!-- tampered -->\n")
    with pytest.raises(ModelFileError, match=r"g1.xml fails its SHA-256 check"):
        load_robot("g1", model_dir=copy)


def test_position_to_motor(g1):
    torque_g1 = position_to_motor(g1)
    assert all(a.kind == "torque" for a in torque_g1.actuators.values())
    for name, a in torque_g1.actuators.items():
        assert a.ctrl_range == g1.actuator(name).force_range
    np.testing.assert_array_equal(torque_g1.mj_model.key_ctrl, 0.0)
    assert torque_g1.source.edits[-1] == "position actuators -> torque motors: 29 actuators"
    assert g1.actuator("left_knee_joint").kind == "position"  # the original is unchanged


def test_position_to_motor_on_unnamed_actuators():
    """Actuators without a name (named after their joint in mbctl) are converted by index."""
    from mbctl.robots import load_robot as load

    xml = """<mujoco><worldbody><body name="l1"><joint name="a" axis="0 0 1"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02"/>
      <body name="l2" pos="0.3 0 0"><joint name="b" axis="0 0 1"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02"/></body></body></worldbody>
      <actuator><position joint="a" kp="50" forcerange="-9 9"/><position joint="b" kp="50" forcerange="-4 4"/>
      </actuator></mujoco>"""
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "arm.xml"
        path.write_text(xml)
        robot = position_to_motor(load(path))
    assert [a.kind for a in robot.actuators.values()] == ["torque", "torque"]
    assert robot.mj_model.actuator_ctrlrange.tolist() == [[-9.0, 9.0], [-4.0, 4.0]]
