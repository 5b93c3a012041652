"""Collision pairs by name (``mbctl.robots.collision``) on a robot and scene built in code."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from mbctl.robots import UnknownNameError, load_robot
from mbctl.robots.collision import CollisionPair, closest_pairs, geom_set, pair_distances, resolve_pairs
from mbctl.robots.exceptions import CollisionPairError

#: A rotated floating trunk with two arms (a ball and a hinge each), a welded head, a geom that
#: cannot collide (contype 0), a default class, a model <exclude>; the scene adds a floor and a
#: free box.
DOLL = """
<mujoco model="doll">
  <compiler angle="radian" autolimits="true"/>
  <default><default class="limb"><geom type="capsule" size="0.03"/></default></default>
  <worldbody>
    <body name="trunk" pos="0 0 1" quat="0.96 0 0.28 0">
      <freejoint name="root"/>
      <geom name="trunk_box" type="box" size="0.1 0.15 0.2"/>
      <geom name="trunk_light" type="sphere" size="0.05" pos="0 0 0.3" contype="0" conaffinity="0"/>
      <body name="head" pos="0 0 0.3"><geom name="head_ball" type="sphere" size="0.08"/></body>
      <body name="left_upper" pos="0 0.2 0.15">
        <joint name="left_shoulder" type="ball"/>
        <geom name="left_upper_geom" class="limb" fromto="0 0 0 0 0 -0.25"/>
        <body name="left_fore" pos="0 0 -0.25">
          <joint name="left_elbow" axis="0 1 0" range="-2.5 0.1"/>
          <geom name="left_fore_geom" class="limb" fromto="0 0 0 0.25 0 0"/>
        </body>
      </body>
      <body name="right_upper" pos="0 -0.2 0.15">
        <joint name="right_shoulder" type="ball"/>
        <geom name="right_upper_geom" class="limb" fromto="0 0 0 0 0 -0.25"/>
        <body name="right_fore" pos="0 0 -0.25">
          <joint name="right_elbow" axis="0 1 0" range="-2.5 0.1"/>
          <geom name="right_fore_geom" class="limb" fromto="0 0 0 0.25 0 0"/>
        </body>
      </body>
    </body>
  </worldbody>
  <contact><exclude body1="left_fore" body2="right_fore"/></contact>
  <actuator>
    <motor joint="left_elbow"/><motor joint="right_elbow"/>
  </actuator>
</mujoco>
"""

SCENE = """
<mujoco model="doll_scene">
  <include file="doll.xml"/>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    <body name="box" pos="0.5 0 0.1"><freejoint/><geom name="box_geom" type="box" size="0.1 0.1 0.1"/></body>
  </worldbody>
</mujoco>
"""


@pytest.fixture(scope="module")
def doll(tmp_path_factory):
    folder = tmp_path_factory.mktemp("doll")
    (folder / "doll.xml").write_text(DOLL)
    (folder / "scene.xml").write_text(SCENE)
    return load_robot(folder / "doll.xml", folder / "scene.xml")


def _names(robot, pairs):
    m = robot.mj_model
    return {tuple(sorted(mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, int(g)) for g in pair))
            for pair in pairs.ids}


def test_robot_against_itself_excludes_adjacent_welded_excluded_and_non_colliding(doll):
    pairs = resolve_pairs(doll, [CollisionPair(("robot",), ("robot",))])
    names = _names(doll, pairs)
    # trunk/upper arms are parent and child, and so are upper arm/forearm; the head is welded to the
    # trunk, so it counts as the upper arms' parent too; the forearms are excluded by the model;
    # trunk_light never collides
    assert names == {
        ("head_ball", "left_fore_geom"), ("head_ball", "right_fore_geom"),
        ("left_fore_geom", "trunk_box"), ("right_fore_geom", "trunk_box"),
        ("left_upper_geom", "right_upper_geom"), ("left_fore_geom", "right_upper_geom"),
        ("left_upper_geom", "right_fore_geom"),
    }
    assert np.all(pairs.ids[:, 0] < pairs.ids[:, 1]) and len(pairs.labels) == len(pairs)


def test_sides_by_geom_body_keyword_and_group(doll):
    assert _names(doll, resolve_pairs(doll, [CollisionPair.parse("left_fore:trunk_box")])) == {
        ("left_fore_geom", "trunk_box")}
    scene = resolve_pairs(doll, [CollisionPair.parse("left_fore,right_fore:scene")])
    assert _names(doll, scene) == {("floor", "left_fore_geom"), ("box_geom", "left_fore_geom"),
                                   ("floor", "right_fore_geom"), ("box_geom", "right_fore_geom")}
    assert set(geom_set(doll, "group=0")) >= set(geom_set(doll, "robot"))
    trunk_box = mujoco.mj_name2id(doll.mj_model, mujoco.mjtObj.mjOBJ_GEOM, "trunk_box")
    assert geom_set(doll, "trunk") == (trunk_box,)
    # the union of two named pairs is deduplicated
    both = resolve_pairs(doll, [CollisionPair.parse("left_fore:trunk"),
                                CollisionPair.parse("trunk:left_fore")])
    assert len(both) == 1


def test_bad_names_and_empty_pairs_are_refused_with_the_reason(doll):
    with pytest.raises(UnknownNameError, match="Did you mean 'left_fore'"):
        resolve_pairs(doll, [CollisionPair.parse("left_for:trunk")])
    with pytest.raises(UnknownNameError, match="keyword"):
        geom_set(doll, "group=9")
    with pytest.raises(CollisionPairError, match="leaves no geom pair.*adjacent bodies, excluded"):
        resolve_pairs(doll, [CollisionPair.parse("left_fore:right_fore")])
    with pytest.raises(CollisionPairError, match="a collision pair is A:B"):
        CollisionPair.parse("left_fore")
    with pytest.raises(CollisionPairError, match="names on both sides"):
        CollisionPair.parse("left_fore:")


def test_distances_are_mujocos_and_the_closest_pair_is_named(doll):
    pairs = resolve_pairs(doll, [CollisionPair.parse("head:left_fore")])
    q = doll.neutral_q()
    q[:3] = [0.0, 0.0, 1.0]
    closest = closest_pairs(doll, np.stack([q, q]), pairs)
    assert [c.pair for c in closest] == ["head_ball/left_fore_geom"] * 2
    data = mujoco.MjData(doll.mj_model)
    doll.plant_qpos(q, data.qpos)
    mujoco.mj_kinematics(doll.mj_model, data)
    fromto = np.zeros((1, 6))
    d = pair_distances(doll.mj_model, data, pairs.ids, fromto=fromto)
    # sphere (r 0.08) at the head, capsule (r 0.03) along the forearm: centre distance minus radii
    head = data.geom_xpos[pairs.ids[0, 0]]
    a, b = data.geom_xpos[pairs.ids[0, 1]], data.xpos[doll.body_id("left_fore")]
    axis = (a - b) / np.linalg.norm(a - b)
    t = np.clip((head - b) @ axis, 0.0, 0.25)
    expected = np.linalg.norm(head - (b + t * axis)) - 0.08 - 0.03
    assert d[0] == pytest.approx(expected, abs=1e-9) and closest[0].distance_m == pytest.approx(expected)
    assert np.linalg.norm(fromto[0, 3:] - fromto[0, :3]) == pytest.approx(expected, abs=1e-9)


# Two upright arms on a base that slides down to the floor; each arm swings toward the other.
TWO_ARMS = """
<mujoco>
  <worldbody>
    <geom name="floor" type="plane" size="1 1 0.1"/>
    <body name="base" pos="0 0 0.5">
      <joint name="drop" type="slide" axis="0 0 1"/>
      <geom name="base" type="box" size="0.05 0.05 0.05"/>
      <body name="a" pos="0 0.1 0"><joint name="ja" axis="1 0 0"/>
        <geom name="ga" type="capsule" fromto="0 0 0 0 0 0.3" size="0.02"/></body>
      <body name="b" pos="0 -0.1 0"><joint name="jb" axis="1 0 0"/>
        <geom name="gb" type="capsule" fromto="0 0 0 0 0 0.3" size="0.02"/></body>
    </body>
  </worldbody>
  <actuator><motor joint="drop"/><motor joint="ja"/><motor joint="jb"/></actuator>
</mujoco>
"""


def test_self_clearance_sees_the_robots_own_pairs_within_the_margin(tmp_path):
    from mbctl.robots.collision import SelfClearance

    path = tmp_path / "two_arms.xml"
    path.write_text(TWO_ARMS)
    robot = load_robot(path)
    m = robot.mj_model
    ga, gb = m.geom("ga").id, m.geom("gb").id
    clearance = SelfClearance(robot, 0.03, [0.0, 0.0, 0.0])
    assert robot.mj_model.geom_margin.max() == 0.0  # the robot's model is untouched (a copy has the margin)
    # arm a tilted 0.5 rad: its tip 16 mm from arm b's surface, inside 30 mm; at 0.3 rad, 71 mm
    assert clearance.pairs([0.0, 0.5, 0.0]) == {(ga, gb)}
    assert not clearance.touches([0.0, 0.3, 0.0])
    assert not clearance.touches([-0.47, 0.0, 0.0])  # the base on the floor: not a pair of the robot's own
    # pairs already that close at the start are neighbours, not counted
    assert not SelfClearance(robot, 0.03, [0.0, 0.5, 0.0]).touches([0.0, 0.5, 0.0])
