"""The bodies on the floor from MuJoCo's floor-contact counts, against the contacts' geom pairs."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from mbctl.robots import load_robot
from mbctl.robots.commands import torque
from mbctl.robots.edits import add_floor_sensors, floor_sensor_name
from mbctl.robots.exceptions import RobotError, UnknownNameError
from mbctl.sim.contacts import FloorContacts, FloorSensors
from mbctl.sim.monitor import PlantMonitor
from mbctl.sim.simulator import Simulator


def _leg(name: str, x: float, y: float) -> str:
    return (f'<body name="leg_{name}" pos="{x} {y} -0.02">'
            f'<joint name="hip_{name}" axis="0 1 0" stiffness="40" damping="2"/>'
            f'<geom type="capsule" fromto="0 0 0 0 0 -0.2" size="0.01" mass="0.2"/>'
            f'<body name="foot_{name}" pos="0 0 -0.2"><geom type="sphere" size="0.02" mass="0.1"/></body>'
            f'</body>')


# A stool whose legs (capsules that collide too) fold when its hip motors push: the seat and the legs
# reach the floor; a box on the floor beside it that a foot lands on, and a free ball (scene).
STOOL = f"""
<mujoco model="stool">
  <option timestep="0.002"/>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    <body name="seat" pos="0 0 0.265">
      <freejoint name="root"/>
      <geom name="seat" type="box" size="0.15 0.15 0.02" mass="2"/>
      {_leg("a", 0.12, 0.0)}{_leg("b", -0.12, 0.1)}{_leg("c", -0.12, -0.1)}
    </body>
    <body name="step" pos="0.3 0 0.03"><geom type="box" size="0.06 0.2 0.03"/></body>
    <body name="ball" pos="1 1 0.3"><freejoint/><geom type="sphere" size="0.05" mass="5"/></body>
  </worldbody>
  <actuator>
    <motor name="hip_a" joint="hip_a" ctrlrange="-150 150"/>
    <motor name="hip_b" joint="hip_b" ctrlrange="-150 150"/>
    <motor name="hip_c" joint="hip_c" ctrlrange="-150 150"/>
  </actuator>
</mujoco>
"""
FEET = ("foot_a", "foot_b", "foot_c")


@pytest.fixture()
def stool(tmp_path):
    path = tmp_path / "stool.xml"
    path.write_text(STOOL)
    return load_robot(path)


def test_add_floor_sensors_counts_the_robots_and_each_bodys_floor_contacts(stool):
    counted = add_floor_sensors(stool, FEET)
    assert add_floor_sensors(counted, FEET[:2]) is counted  # idempotent
    m = counted.mj_model
    assert m.nsensor == 4 and stool.mj_model.nsensor == 0  # the original is unchanged
    assert {m.sensor(i).name for i in range(4)} == {floor_sensor_name(None), *map(floor_sensor_name, FEET)}
    assert "floor contact counts on the robot, foot_a, foot_b, foot_c" in counted.source.edits[-1]
    sensors = FloorSensors(m, counted.tree_root_id, counted.robot_body_ids)
    assert sensors.names == FEET and sensors.index is not None
    assert FloorSensors(stool.mj_model, stool.tree_root_id, stool.robot_body_ids).index is None
    with pytest.raises(UnknownNameError, match="nope"):
        add_floor_sensors(stool, ["nope"])


def test_floor_sensors_need_one_tree_and_their_names_free(tmp_path, stool):
    two = tmp_path / "two.xml"
    two.write_text("""<mujoco><worldbody><geom type="plane" size="1 1 0.1"/>
      <body name="a" pos="0 0 0.5"><freejoint/><geom type="sphere" size="0.1"/></body>
      <body name="b" pos="1 0 0.5"><freejoint/><geom type="sphere" size="0.1"/></body>
      </worldbody></mujoco>""")
    pair = load_robot(two, roots=("a", "b"))
    assert pair.tree_root_id is None and stool.tree_root_id == stool.body_id("seat")
    with pytest.raises(RobotError, match="one tree of bodies"):
        add_floor_sensors(pair, ["a"])
    clash = tmp_path / "clash.xml"
    clash.write_text(STOOL.replace("</actuator>", '</actuator><sensor><framepos name="foot_a_floor_contacts" '
                                                  'objtype="body" objname="foot_a"/></sensor>'))
    with pytest.raises(RobotError, match="'foot_a_floor_contacts' that is not a contact sensor"):
        add_floor_sensors(load_robot(clash), FEET)


def test_the_monitor_names_the_bodies_on_the_floor_as_the_geom_pairs_do(stool):
    """Stepping, folding onto the seat and the legs, a foot on the box: equal to the geom pairs' answer."""
    counted = add_floor_sensors(stool, FEET)
    sim = Simulator(counted)
    monitor = PlantMonitor(sim).attach()
    assert monitor._read is not None  # the counts serve this robot
    m, d = sim.model, sim.data
    pairs = FloorContacts(m, np.flatnonzero(m.geom_bodyid == 0), bodies=counted.robot_body_ids)
    seen, from_pairs = set(), 0
    sim.send(torque([0.0, 0.0, 0.0]))
    for k in range(900):
        if k == 150:  # the hips fold: two legs and then the seat reach the floor (from step ~480)
            sim.send(torque([150.0, 150.0, 150.0]))
        if k == 300:
            m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_SENSOR  # off at run time: the pairs serve
        if k == 400:
            m.opt.disableflags &= ~int(mujoco.mjtDisableBit.mjDSBL_SENSOR)
        sim.step()
        expected = tuple(pairs.bodies(d))
        assert monitor.floor_bodies == expected, k
        seen.add(expected)
        from_pairs += monitor._floor_geoms is not None
    assert ("foot_a", "foot_b", "foot_c") in seen  # standing: the counts alone answer
    assert {("foot_b", "foot_c", "leg_b", "leg_c"), ("seat",)} <= seen  # counts disagree: pairs answer
    assert 100 + 300 <= from_pairs < 900  # the 100 steps without sensors, and most steps after ~480


def test_the_g1_falling_names_the_bodies_on_the_floor_as_the_geom_pairs_do(g1_torque):
    """The whole-body jobs' G1, limp from standing until it lies on the floor: the same bodies every step."""
    from mbctl.robots.g1 import FOOT_BODIES, KEYFRAME

    sim = Simulator(g1_torque)
    sim.reset(KEYFRAME)
    monitor = PlantMonitor(sim).attach()
    assert monitor._floor_sensors is not None and monitor._floor_sensors.names == tuple(sorted(FOOT_BODIES))
    m, d = sim.model, sim.data
    pairs = FloorContacts(m, np.flatnonzero(m.geom_bodyid == 0), bodies=g1_torque.robot_body_ids)
    seen = set()
    for _ in range(1000):  # 2 s without torques
        sim.step()
        assert monitor.floor_bodies == tuple(pairs.bodies(d))
        seen.add(monitor.floor_bodies)
    assert tuple(sorted(FOOT_BODIES)) in seen and any(set(s) - set(FOOT_BODIES) for s in seen)
