"""Contact sums read from MuJoCo's net-force contact sensors against the loop over the contacts."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from mbctl.robots import load_robot
from mbctl.robots.edits import add_contact_sensors, contact_sensor_name
from mbctl.robots.exceptions import RobotError, UnknownNameError
from mbctl.sim.contacts import ContactSensor, sums_block

SENSOR = '<contact name="{0}_contact" body1="{0}" reduce="netforce" data="found force torque pos"/>'

# A tilted "foot" (its root turned 0.3 rad about z, sole spheres of two heights, an inner frame), a
# box resting on the foot (the foot's geoms are geom1 in some contacts, geom2 in others) and a ball
# next to it; both freely moving, pushed sideways in the test.
SCENE = """
<mujoco>
  <option timestep="0.002"/>
  <default><geom friction="0.7"/><default class="sole"><geom type="sphere" size="0.012"/></default></default>
  <worldbody>
    <geom name="floor" type="plane" size="3 3 0.1"/>
    <body name="foot" pos="0.2 -0.1 0.06" euler="0 0 0.3">
      <freejoint/>
      <geom name="plate" type="box" size="0.1 0.05 0.01" mass="1.5"/>
      <frame pos="0 0 -0.02">
        <geom class="sole" name="s0" pos="0.08 0.04 -0.01"/>
        <geom class="sole" name="s1" pos="0.08 -0.04 -0.01"/>
        <geom class="sole" name="s2" pos="-0.08 0.04 -0.012"/>
        <geom class="sole" name="s3" pos="-0.08 -0.04 -0.012"/>
      </frame>
      <geom name="fin" type="box" size="0.01 0.01 0.01" pos="0 0 0.05" contype="0" conaffinity="0"/>
    </body>
    <body name="load" pos="0.22 -0.1 0.12">
      <freejoint/>
      <geom name="load" type="box" size="0.03 0.03 0.03" mass="2"/>
    </body>
    <body name="ball" pos="0.6 0.3 0.1"><freejoint/><geom name="ball" type="sphere" size="0.04"/></body>
  </worldbody>
  <sensor>{sensors}</sensor>
</mujoco>
"""


def _model(bodies=("foot", "load")) -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(SCENE.format(sensors="".join(SENSOR.format(b) for b in bodies)))


def _groups(m: mujoco.MjModel) -> dict[str, list[int]]:
    return {b: np.flatnonzero(m.geom_bodyid == m.body(b).id).tolist() for b in ("foot", "load")}


def test_sensor_sums_equal_the_loop_over_the_contacts_while_pushed():
    m = _model()
    d = mujoco.MjData(m)
    sensor = ContactSensor(m, _groups(m))
    assert sensor.from_sensors
    checked = 0
    nets, sums = [], []
    for k in range(600):
        d.xfrc_applied[m.body("foot").id, :2] = (8 * np.sin(k / 40), 6 * np.cos(k / 55))
        mujoco.mj_step(m, d)
        fast = sensor.sums(d)
        loop = sensor.sums_from(sensor.loop_net(d))
        nets.append(sensor.net(d))
        sums.append(fast)
        for a, b in zip(fast, loop, strict=True):
            assert a[5] == b[5]  # contacts
            scale = max(1.0, abs(b[2]))
            np.testing.assert_allclose(a[:5], b[:5], atol=1e-9 * scale)
        checked += fast[0][5] > 0 and fast[1][5] > 0
    assert checked > 500  # the load stayed on the foot: contacts on both sides of the foot's geoms
    # the same sums for every period at once (a log's batch), and from an array as from a list
    np.testing.assert_array_equal(sums_block(np.array(nets)), np.array(sums, dtype=float))
    assert sensor.sums_from(np.array(nets[-1])) == sums[-1]
    load = sensor.measure(d)["load"]
    assert load.normal_n == pytest.approx(2 * 9.81, rel=0.05)  # roughly its weight, the foot moving


def test_the_cop_is_where_the_horizontal_moment_vanishes():
    """On the floor alone (the load lifted away), the foot's CoP is the z-force-weighted contact point."""
    m = _model()
    d = mujoco.MjData(m)
    d.qpos[m.jnt_qposadr[m.body("load").jntadr[0]] + 2] = 2.0  # the load far above
    mujoco.mj_step(m, d, 300)
    sensor = ContactSensor(m, _groups(m))
    f6 = np.zeros(6)
    F = np.zeros(3)
    fz_p = np.zeros(2)
    foot = m.body("foot").id
    for i in range(d.ncon):
        c = d.contact[i]
        if m.geom_bodyid[c.geom2] == foot:
            mujoco.mj_contactForce(m, d, i, f6)
            f = c.frame.reshape(3, 3).T @ f6[:3]
            F += f
            fz_p += f[2] * c.pos[:2]
    cop = sensor.measure(d)["foot"].cop_W
    # the sole spheres' contacts lie 2 mm apart in height: the CoP moves by that times |ft| / fz
    np.testing.assert_allclose(cop[:2], fz_p / F[2], atol=2e-3 * np.hypot(F[0], F[1]) / F[2] + 1e-12)
    np.testing.assert_allclose(sensor.measure(d)["foot"].force_W, F, atol=1e-9)


def test_groups_without_a_matching_sensor_use_the_loop():
    m = _model(bodies=("foot",))
    g = _groups(m)
    assert not ContactSensor(m, g).from_sensors  # the load has no sensor
    m = _model()
    assert not ContactSensor(m, {"foot": g["foot"][:3], "load": g["load"]}).from_sensors  # part of a foot
    assert not ContactSensor(m, {"both": g["foot"] + g["load"]}).from_sensors  # two bodies
    fin = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "fin")
    no_fin = [x for x in g["foot"] if x != fin]
    assert ContactSensor(m, {"foot": no_fin, "load": g["load"]}).from_sensors  # the fin never collides
    sensor = ContactSensor(m, g)
    m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_SENSOR
    assert not sensor.from_sensors  # sensors off: the loop, every period


def test_sensors_off_gives_the_loop_sums():
    m = _model()
    d = mujoco.MjData(m)
    mujoco.mj_step(m, d, 200)
    sensor = ContactSensor(m, _groups(m))
    on = sensor.sums(d)
    m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_SENSOR
    mujoco.mj_step(m, d)  # sensordata keeps the last values computed: the loop must not read them
    np.testing.assert_allclose(sensor.sums(d)[0][:5], sensor.sums_from(sensor.loop_net(d))[0][:5], atol=1e-12)
    assert on[0][2] > 0


def test_add_contact_sensors_on_a_robot(tmp_path):
    path = tmp_path / "scene.xml"
    path.write_text(SCENE.format(sensors=""))
    robot = load_robot(path)
    with_sensors = add_contact_sensors(robot, ["foot", "load"])
    assert add_contact_sensors(with_sensors, ["foot"]) is with_sensors  # idempotent
    m = with_sensors.mj_model
    assert m.nsensor == 2 and m.sensor(contact_sensor_name("foot")).dim[0] == 10
    assert "contact sensors (net force) on foot, load" in with_sensors.source.edits[-1]
    assert ContactSensor(m, _groups(m)).from_sensors
    assert robot.mj_model.nsensor == 0  # the original is unchanged
    with pytest.raises(UnknownNameError, match="nope"):
        add_contact_sensors(robot, ["nope"])
    clash = tmp_path / "clash.xml"
    clash.write_text(SCENE.format(sensors='<framepos name="foot_contact" objtype="body" objname="foot"/>'))
    with pytest.raises(RobotError, match="'foot_contact' that is not a contact sensor"):
        add_contact_sensors(load_robot(clash), ["foot"])


def test_the_g1_feet_read_from_the_sensors_equal_the_loop(g1_torque):
    """The whole-body jobs' G1: its monitor reads each foot from MuJoCo's sensor, as the loop sums it."""
    from mbctl.robots.g1 import FOOT_BODIES, KEYFRAME, crouched_start
    from mbctl.sim.simulator import Simulator

    sim = Simulator(g1_torque)
    sim.reset(KEYFRAME)
    q0 = crouched_start(g1_torque)
    sim.set_state(q0, np.zeros(g1_torque.nv))
    m, d = sim.model, sim.data
    feet = {b: np.flatnonzero(m.geom_bodyid == m.body(b).id).tolist() for b in FOOT_BODIES}
    sensor = ContactSensor(m, feet)
    assert sensor.from_sensors
    d.xfrc_applied[1, :2] = (40.0, -25.0)  # a lean (no torques: the robot sinks): the feet's forces move
    most = 0.0
    for _ in range(150):
        mujoco.mj_step(m, d)
        for a, b in zip(sensor.sums(d), sensor.sums_from(sensor.loop_net(d)), strict=True):
            assert a[5] == b[5]
            np.testing.assert_allclose(a[:5], b[:5], atol=1e-9 * max(1.0, abs(b[2])))
        most = max(most, sum(s[2] for s in sensor.sums(d)))
    assert most > float(m.body_subtreemass[1]) * 9.81  # the feet carried the robot
