"""A scene must hold the robot file's robot: another robot, or another variant of it, is refused.

Each case writes a robot file and a scene that includes a different file (another robot, the
variant without the gripper, the variant with an arm, a heavier link, a slide for a hinge), as a
user who picks the wrong scene would.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from mbctl.exceptions import ToolkitError
from mbctl.robots import SceneMismatchError, load_robot
from mbctl.robots.registry import ASSETS

GRIPPER = """
        <body name="finger_left" pos="0.3 0.02 0">
          <joint name="finger_left" type="slide" axis="0 1 0" range="0 0.02"/>
          <inertial pos="0.02 0 0" mass="0.05" diaginertia="1e-5 1e-5 1e-5"/></body>
        <body name="finger_right" pos="0.3 -0.02 0">
          <joint name="finger_right" type="slide" axis="0 -1 0" range="0 0.02"/>
          <inertial pos="0.02 0 0" mass="0.05" diaginertia="1e-5 1e-5 1e-5"/></body>"""


def arm_xml(gripper: bool = True, fore_mass: str = "0.7", elbow: str = 'axis="0 1 0"') -> str:
    """A 2-link arm on a mount, with a two-finger gripper (4 dof) or without (2 dof)."""
    fingers = GRIPPER if gripper else ""
    motors = '<motor joint="finger_left"/><motor joint="finger_right"/>' if gripper else ""
    return f"""<mujoco model="arm">
  <compiler angle="radian" inertiafromgeom="false" autolimits="true"/>
  <worldbody>
    <body name="mount" pos="0 0 0.3">
      <inertial pos="0 0 0" mass="3" diaginertia="0.01 0.01 0.01"/>
      <body name="upper" pos="0 0 0.1"><joint name="shoulder" axis="0 1 0"/>
        <inertial pos="0.15 0 0" mass="1.2" diaginertia="0.001 0.01 0.01"/>
        <body name="fore" pos="0.3 0 0"><joint name="elbow" {elbow}/>
          <inertial pos="0.12 0 0" mass="{fore_mass}" diaginertia="0.001 0.005 0.005"/>
          <site name="tool" pos="0.25 0 0"/>{fingers}
        </body>
      </body>
    </body>
  </worldbody>
  <actuator><motor joint="shoulder"/><motor joint="elbow"/>{motors}</actuator>
</mujoco>"""


def quadruped_xml(arm: bool = False) -> str:
    """A floating trunk with two legs, and with an arm on top (the arm variant)."""
    legs = "".join(
        f"""<body name="{leg}_thigh" pos="{x} {y} 0"><joint name="{leg}_hip" axis="0 1 0"/>
          <inertial pos="0 0 -0.1" mass="1" diaginertia="0.01 0.01 0.001"/>
          <body name="{leg}_calf" pos="0 0 -0.2"><joint name="{leg}_knee" axis="0 1 0"/>
            <inertial pos="0 0 -0.1" mass="0.3" diaginertia="0.003 0.003 0.0003"/></body></body>"""
        for leg, x, y in (("front", 0.2, 0), ("rear", -0.2, 0))
    )
    arm_xml_ = """<body name="arm_link" pos="0 0 0.1"><joint name="arm_sh0" axis="0 0 1"/>
          <inertial pos="0.1 0 0" mass="0.8" diaginertia="0.001 0.004 0.004"/></body>""" if arm else ""
    motors = "".join(f'<motor joint="{leg}_{j}"/>' for leg in ("front", "rear") for j in ("hip", "knee"))
    motors += '<motor joint="arm_sh0"/>' if arm else ""
    return f"""<mujoco model="quadruped">
  <compiler angle="radian" inertiafromgeom="false"/>
  <worldbody>
    <body name="trunk" pos="0 0 0.5"><freejoint name="floating_base"/>
      <inertial pos="0 0 0" mass="8" diaginertia="0.05 0.2 0.2"/>{legs}{arm_xml_}
    </body>
  </worldbody>
  <actuator>{motors}</actuator>
</mujoco>"""


def scene_of(path: Path) -> str:
    return (f'<mujoco><include file="{path.name}"/><worldbody><geom type="plane" size="2 2 0.1"/>'
            '<body name="box" pos="0.5 0 0.1"><freejoint/><geom type="box" size="0.05 0.05 0.05"/>'
            '<inertial pos="0 0 0" mass="0.3" diaginertia="1e-4 1e-4 1e-4"/>'
            "</body></worldbody></mujoco>")


def write(folder: Path, robot: str, included: str) -> tuple[Path, Path]:
    """The robot file ``robot.xml`` and a scene that includes ``included`` (another file)."""
    robot_file, other = folder / "robot.xml", folder / "variant.xml"
    robot_file.write_text(robot)
    other.write_text(included)
    scene = folder / "scene.xml"
    scene.write_text(scene_of(other))
    return robot_file, scene


def test_the_scene_of_the_robot_loads_and_leaves_props_as_scene(tmp_path):
    robot_file, scene = write(tmp_path, arm_xml(), arm_xml())
    robot = load_robot(robot_file, scene)
    assert list(robot.joints) == ["shoulder", "elbow", "finger_left", "finger_right"]
    assert robot.source.roots == ("mount",) and robot.scene_bodies[0].startswith("box (free")


@pytest.mark.parametrize(
    ("robot", "included", "message"),
    [
        # a robot file with the gripper, a scene of the variant without it (as xarm7 / xarm7_nohand)
        (arm_xml(), arm_xml(gripper=False),
         "joints do not pair by name: only in the robot file: finger_left, finger_right"),
        # a quadruped, a scene of its variant with an arm (as spot / spot_arm)
        (quadruped_xml(), quadruped_xml(arm=True), "joints do not pair by name: only in the scene: arm_sh0"),
        # another robot altogether
        (arm_xml(), quadruped_xml(), "it has no body 'mount', a root body of the robot file's robot"),
        # the same names, a heavier forearm
        (arm_xml(), arm_xml(fore_mass="0.75"), "fore (joint 'elbow'): mass 0.7 vs 0.75 kg"),
        # the same names, a slide where the robot file has a hinge
        (arm_xml(), arm_xml(elbow='type="slide" axis="1 0 0"'),
         "fore (joint 'elbow'): hinge (nq 1, nv 1) in the robot file, slide (nq 1, nv 1) in the scene"),
        # the same joints, the elbow turning about another axis
        (arm_xml(), arm_xml(elbow='axis="0 0 1"'),
         "fore (joint 'elbow'): axis (0, 1, 0) through (0.3, 0, 0.4) m at q0 vs axis (0, 0, 1) through "
         "(0.3, 0, 0) m at q0"),
    ],
    ids=["without-gripper", "with-arm", "another-robot", "heavier-link", "slide-for-hinge", "other-axis"],
)
def test_a_scene_of_another_robot_is_refused_naming_the_first_difference(tmp_path, robot, included, message):
    robot_file, scene = write(tmp_path, robot, included)
    with pytest.raises(SceneMismatchError) as info:
        load_robot(robot_file, scene)
    assert str(info.value).startswith(
        f"The scene {str(scene)!r} does not hold the robot of {str(robot_file.resolve())!r}: "
    )
    assert message in str(info.value)
    assert isinstance(info.value, ToolkitError)
    with pytest.raises(SceneMismatchError, match="does not hold the robot"):  # the parser path too
        load_robot(robot_file, scene, analytic="parser", check=False)


def test_roots_outside_the_robot_file_are_refused(tmp_path):
    robot_file, scene = write(tmp_path, arm_xml(), arm_xml())
    with pytest.raises(SceneMismatchError, match="the root body 'box' is not a body of the robot file"):
        load_robot(robot_file, scene, roots=("box",))


def test_the_arm_with_the_g1_scene_is_refused(g1, tmp_path):
    arm = tmp_path / "arm.xml"
    arm.write_text((ASSETS / "two_link_arm.xml").read_text())
    with pytest.raises(SceneMismatchError, match="it has no body 'link1'"):
        load_robot(arm, g1.source.scene_file)


def test_cli_xcheck_exits_2_before_any_cross_check(tmp_path):
    robot_file, scene = write(tmp_path, arm_xml(), arm_xml(gripper=False))
    out = subprocess.run(
        [sys.executable, "-m", "mbctl.cli", "xcheck", str(robot_file), "--scene", str(scene), "--states", "5",
         "--output", str(tmp_path / "out")],
        capture_output=True, text=True, timeout=120, env=dict(os.environ),
    )
    assert out.returncode == 2, out.stdout + out.stderr
    assert "cross-check of" not in out.stdout and "PASS" not in out.stdout
    assert "only in the robot file: finger_left, finger_right" in out.stderr
