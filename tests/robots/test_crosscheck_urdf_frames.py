"""A URDF against its MJCF: sites pair with frames of a site's kind, a fixed base keeps its root's mass.

One 3-link fixed-base arm is written both as MJCF and as URDF: a 5 kg base link welded to the
world, two hinges and a slide joint called ``finger``, and a MuJoCo site also called ``finger`` 72 mm
from the slide's origin. In the URDF the site is a link ``finger`` on a fixed joint (a URDF has no
sites), or is absent; the slide joint keeps its name, so Pinocchio has a JOINT frame ``finger``
too. aloha's finger sites and joints share their names in the same way.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from mbctl.robots import load_robot
from mbctl.robots.crosscheck import crosscheck
from mbctl.robots.crosscheck.frames import match_frames, site_frame

#: The site's offset [m] from the slide's origin: the FK error of a site paired with the joint.
SITE_OFFSET = (0.06, 0.0, 0.04)

MJCF = f"""<mujoco model="arm3"><compiler angle="radian"/><worldbody>
<body name="base"><inertial pos="0 0 0.05" mass="5" diaginertia="0.05 0.05 0.02"/>
 <body name="link1" pos="0 0 0.1"><joint name="j1" axis="0 0 1" range="-2 2"/>
  <inertial pos="0 0 0.15" mass="2" diaginertia="0.02 0.02 0.005"/>
  <body name="link2" pos="0 0 0.3"><joint name="j2" axis="0 1 0" range="-2 2"/>
   <inertial pos="0 0 0.15" mass="1.5" diaginertia="0.015 0.015 0.004"/>
   <body name="link3" pos="0 0 0.3"><joint name="finger" type="slide" axis="1 0 0" range="0 0.05"/>
    <inertial pos="0.02 0 0.02" mass="0.3" diaginertia="1e-4 1e-4 1e-4"/>
    <site name="finger" pos="{' '.join(map(str, SITE_OFFSET))}"/>
   </body></body></body></body></worldbody>
<actuator><motor joint="j1"/><motor joint="j2"/><motor joint="finger"/></actuator></mujoco>"""


def _link(name: str, mass: float, com: str, inertia: tuple[float, float, float]) -> str:
    ixx, iyy, izz = inertia
    return (f'<link name="{name}"><inertial><origin xyz="{com}"/><mass value="{mass}"/>'
            f'<inertia ixx="{ixx}" iyy="{iyy}" izz="{izz}" ixy="0" ixz="0" iyz="0"/></inertial></link>')


def _joint(name: str, kind: str, parent: str, child: str, xyz: str, axis: str, limits: str) -> str:
    lower, upper = limits.split()
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{xyz}"/><axis xyz="{axis}"/>'
            f'<limit lower="{lower}" upper="{upper}" effort="10" velocity="10"/></joint>')


def urdf(j1: str = "j1", site_link: bool = True) -> str:
    """The arm as URDF: the first joint called ``j1``; the site as a link on a fixed joint or not at all."""
    text = ('<?xml version="1.0"?><robot name="arm3">' + _link("base", 5.0, "0 0 0.05", (0.05, 0.05, 0.02))
            + _joint(j1, "revolute", "base", "link1", "0 0 0.1", "0 0 1", "-2 2")
            + _link("link1", 2.0, "0 0 0.15", (0.02, 0.02, 0.005))
            + _joint("j2", "revolute", "link1", "link2", "0 0 0.3", "0 1 0", "-2 2")
            + _link("link2", 1.5, "0 0 0.15", (0.015, 0.015, 0.004))
            + _joint("finger", "prismatic", "link2", "link3", "0 0 0.3", "1 0 0", "0 0.05")
            + _link("link3", 0.3, "0.02 0 0.02", (1e-4, 1e-4, 1e-4)))
    if site_link:
        text += ('<joint name="finger_site" type="fixed"><parent link="link3"/><child link="finger"/>'
                 f'<origin xyz="{" ".join(map(str, SITE_OFFSET))}"/></joint><link name="finger"/>')
    return text + "</robot>"


@pytest.fixture
def write(tmp_path):
    def files(**kwargs):
        (tmp_path / "arm3.xml").write_text(MJCF)
        (tmp_path / "arm3.urdf").write_text(urdf(**kwargs))
        return tmp_path / "arm3.xml", tmp_path / "arm3.urdf"

    return files


def test_a_site_pairs_with_the_link_on_a_fixed_joint_not_the_joint_of_its_name(write):
    """Before: the site was paired with any frame called ``finger`` (here two: a ValueError)."""
    robot = load_robot(*write()[:1], pin_model_file=write()[1], check=False)
    pm = robot.pin_model
    fid = site_frame(pm, "finger")
    assert fid is not None and pm.frames[fid].type == pin.FrameType.BODY
    assert pm.existFrame("finger", pin.FrameType.JOINT)  # the slide joint's frame, never the site's
    frames = match_frames(robot)
    assert "finger" in frames.names and not frames.missing
    report = crosscheck(robot, n_states=10)
    assert report.passed, report.to_text()
    assert report.quantity("fk_position").max_abs_error < 1e-12


def test_a_site_without_its_kind_of_frame_is_not_compared_against_a_joint(write):
    """aloha's case: no URDF link for the site, a joint of its name. Before: paired with the
    joint's frame, FK failed by the 72 mm offset; now the site is listed as not compared."""
    robot = load_robot(*write(site_link=False)[:1], pin_model_file=write(site_link=False)[1], check=False)
    assert site_frame(robot.pin_model, "finger") is None
    assert match_frames(robot).missing == ["site finger"]
    report = crosscheck(robot, n_states=10)
    assert report.passed, report.to_text()
    assert report.quantity("fk_position").max_abs_error < 1e-12  # was 0.072 (np.hypot(0.06, 0.04))
    assert any("no Pinocchio frame" in n and "site finger" in n for n in report.notes)


def test_a_renamed_fixed_base_keeps_its_root_links_mass(write):
    """A joint map rebuilds the model: the 5 kg base link (Pinocchio's universe inertia in a
    fixed-base URDF) was dropped, a false "robot mass differs: Pinocchio 3.8 kg, MuJoCo 8.8 kg"."""
    robot_file, urdf_file = write(j1="joint_a1")
    robot = load_robot(robot_file, pin_model_file=urdf_file, check=False, joint_map={"joint_a1": "j1"})
    assert "joints renamed: joint_a1 -> j1" in robot.source.edits
    assert robot.pin_model.inertias[0].mass == pytest.approx(5.0, abs=1e-12)
    total = sum(inertia.mass for inertia in robot.pin_model.inertias)
    assert total == pytest.approx(float(np.sum(robot.mj_model.body_mass)), abs=1e-12)  # 8.8 kg
    report = crosscheck(robot, n_states=10)
    assert report.passed and not any("mass differs" in n for n in report.notes), report.to_text()


def test_the_load_time_check_pairs_sites_by_the_same_rule(write):
    """The exact twin loads with the agreement check on: its site is the URDF link on a fixed joint
    (before, the check looked for an OP_FRAME only: "missing in Pinocchio: site 'finger'")."""
    robot_file, urdf_file = write()
    robot = load_robot(robot_file, pin_model_file=urdf_file)  # check=True: raises on a mismatch
    assert site_frame(robot.pin_model, "finger") is not None
