"""The plant monitor on a stool built in code: CoM, joint torques, foot wrenches, falls, floor counts."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from mbctl.robots import load_robot
from mbctl.robots.commands import torque
from mbctl.robots.edits import add_floor_sensors, floor_sensor_name
from mbctl.robots.exceptions import RobotError, UnknownNameError
from mbctl.robots.g1 import FallRule
from mbctl.robots.scene import bodies_com
from mbctl.sim.contacts import FloorContacts, FloorSensors, contact_wrenches
from mbctl.sim.exceptions import SimError
from mbctl.sim.monitor import PlantMonitor
from mbctl.sim.simulator import Simulator


def _leg(name: str, x: float, y: float) -> str:
    return (f'<body name="leg_{name}" pos="{x} {y} -0.02">'
            f'<joint name="hip_{name}" axis="0 1 0" stiffness="40" damping="2"/>'
            f'<geom type="capsule" fromto="0 0 0 0 0 -0.2" size="0.01" mass="0.2" contype="0" '
            f'conaffinity="0"/>'
            f'<body name="foot_{name}" pos="0 0 -0.2"><geom name="sole_{name}" type="sphere" size="0.02" '
            f'mass="0.1"/></body></body>')


# A stool: a seat on three legs whose hips are springs with motors, and a ball beside it (scene).
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
HIPS = ("hip_a", "hip_b", "hip_c")


@pytest.fixture()
def stool(tmp_path):
    path = tmp_path / "stool.xml"
    path.write_text(STOOL)
    return load_robot(path)


def test_the_monitor_measures_what_the_plant_did_each_period(stool):
    sim = Simulator(stool)
    monitor = PlantMonitor(sim, fall_rule=FallRule(0.15, FEET).reason, joints=HIPS, wrench_bodies=FEET,
                           count_elsewhere=True).attach()
    command = torque([0.5, -0.25, 0.0])
    for _ in range(400):  # 0.8 s: settled on its feet
        sim.step(command)
    m, d = sim.model, sim.data
    assert "ball" not in stool.bodies and monitor.mass_kg == pytest.approx(2.0 + 3 * 0.3)
    # the CoM of the robot (not of the ball) at the step's start: its root's subtree CoM
    np.testing.assert_allclose(monitor.com_W, d.subtree_com[m.body("seat").id], atol=1e-12)
    np.testing.assert_allclose(monitor.com_W, bodies_com(m, d, stool.robot_body_ids), atol=1e-15)
    np.testing.assert_array_equal(monitor.joint_torques, [0.5, -0.25, 0.0])  # motors, gear 1
    # the feet carry the stool's weight; the wrenches are contact_wrenches' about each foot's origin
    assert monitor.touching.tolist() == [True, True, True]
    assert monitor.wrenches_W[:, 2].sum() == pytest.approx(monitor.mass_kg * 9.81, rel=1e-3)
    feet = [m.body(f).id for f in FEET]
    groups = [[m.geom(f"sole_{f[-1]}").id] for f in FEET]
    _, expected = contact_wrenches(m, d, groups, d.xpos[feet])
    np.testing.assert_array_equal(monitor.wrenches_W, expected)
    assert monitor.contacts_elsewhere == 0 and monitor.fall_reason is None
    assert monitor.time_s == pytest.approx(d.time - sim.control_period_s)
    # the hips fold: the seat lands on the floor, which the rule calls a fall and the count sees
    for _ in range(400):
        sim.step(torque([150.0, 150.0, 150.0]))
    assert monitor.contacts_elsewhere >= 1 and monitor.floor_bodies == ("seat",)
    assert monitor.fall_reason is not None and monitor.fall_reason.startswith("base at 0.14")
    assert 0.8 < monitor.fall_time_s < 1.6


def test_a_periods_sample_carries_the_time_of_the_state_its_command_saw_bit_for_bit(stool):
    # its time is the same float as the state's (t + T - T is not always t: the job's CoM error
    # compares the two and went cycle by cycle when they differed by 1e-16 s)
    sim = Simulator(stool, control_period_s=0.006)
    monitor = PlantMonitor(sim).attach()
    for k in range(600):
        state = sim.read_state()
        if k % 2:
            sim.sync()
        else:
            sim.step(n=3)
        assert monitor.time_s == state.time_s, k
    held_from = sim.time_s
    sim.hold(2)  # a plant's clock running with the robot held still: the period began where it was
    assert monitor.time_s == held_from and sim.time_s == pytest.approx(held_from + 0.004)


def test_the_monitor_refuses_joints_it_cannot_sample_and_unknown_bodies(stool):
    sim = Simulator(stool)
    with pytest.raises(SimError, match=r"joint torques are sampled on one-dof joints \(hinge, slide\); "
                                       r"\['root'\] are not"):
        PlantMonitor(sim, joints=("root",))
    with pytest.raises(UnknownNameError, match="nope"):
        PlantMonitor(sim, wrench_bodies=("nope",))
    with pytest.raises(UnknownNameError, match="knee"):
        PlantMonitor(sim, joints=("knee",))
    idle = PlantMonitor(sim).attach()  # nothing asked: nothing sampled but the CoM and the floor
    sim.step(torque([0.0, 0.0, 0.0]))
    assert idle.joint_torques.shape == (0,) and idle.wrenches_W.shape == (0, 6)
    assert idle.contacts_elsewhere == 0


def test_plant_kinematics_places_the_robot_like_the_simulator(stool):
    from mbctl.robots.plant_kinematics import PlantKinematics

    sim = Simulator(stool)
    sim.step(torque([1.0, 2.0, 3.0]), n=50)
    sim.forward()
    q = sim.read_state().q
    data = PlantKinematics(robot=stool).at(q)
    np.testing.assert_allclose(data.xpos[1:-1], sim.data.xpos[1:-1], atol=1e-12)  # the robot's bodies
    np.testing.assert_allclose(data.qpos[-7:], stool.mj_model.qpos0[-7:])  # the scene's ball at qpos0
    again = PlantKinematics(stool.mj_model).at_qpos(sim.data.qpos)
    np.testing.assert_allclose(again.site_xpos, sim.data.site_xpos)
    np.testing.assert_allclose(again.xipos, sim.data.xipos, atol=1e-12)
    from mbctl.robots.exceptions import RobotError

    with pytest.raises(RobotError, match="PlantKinematics.at takes a robot configuration: give the robot"):
        PlantKinematics(stool.mj_model).at(q)
    assert mujoco.mj_name2id(stool.mj_model, mujoco.mjtObj.mjOBJ_BODY, "ball") == stool.mj_model.nbody - 1


def _forces_per_contact(m: mujoco.MjModel, d: mujoco.MjData, groups: dict) -> dict:
    """Per group, by ``mj_contactForce`` contact by contact: force (3,) [N] in W, fz times the CoP's x, y
    (where the moment has no horizontal part, on the plane through the |f|-weighted contact points),
    count, and the z-force-weighted x, y (the CoP's classic formula, equal for coplanar contacts)."""
    forces: dict = {name: [] for name in groups}
    f6 = np.zeros(6)
    for i in range(d.ncon):
        con = d.contact[i]
        mujoco.mj_contactForce(m, d, i, f6)
        f_W = con.frame.reshape(3, 3).T @ f6[:3]  # on geom2; the opposite on geom1
        for geom, sign in ((con.geom2, 1.0), (con.geom1, -1.0)):
            for name, geoms in groups.items():
                if int(geom) in geoms:
                    forces[name].append((sign * f_W, np.array(con.pos)))
    out = {}
    for name, fp in forces.items():
        if not fp:
            out[name] = [np.zeros(3), np.zeros(2), 0, np.zeros(2)]
            continue
        f, p = (np.array(x) for x in zip(*fp, strict=True))
        w = np.linalg.norm(f, axis=1)
        c = w @ p / w.sum()
        F, N = f.sum(axis=0), np.cross(p - c, f).sum(axis=0)
        out[name] = [F, F[2] * c[:2] + np.array([-N[1], N[0]]), len(fp), f[:, 2] @ p[:, :2]]
    return out


@pytest.mark.parametrize("lift_rad", [0.0, 0.5], ids=["both feet", "single support"])
def test_the_monitors_foot_sums_are_mujocos_contact_forces_on_the_g1(g1, lift_rad):
    from mbctl.robots.collision import body_geoms
    from mbctl.robots.g1 import FEET as G1_FEET
    from mbctl.robots.g1 import crouched_start

    m = g1.mj_model
    feet = {f: body_geoms(m, int(m.site_bodyid[g1.site_id(f)])) for f in G1_FEET}
    sim = Simulator(g1)
    sim.reset("stand")
    q = crouched_start(g1).copy()  # the left foot lifted by bending its knee and hip
    q[g1.joint("left_knee_joint").idx_q] += lift_rad
    q[g1.joint("left_hip_pitch_joint").idx_q] -= lift_rad / 2
    sim.set_state(q, np.zeros(g1.nv))
    monitor = PlantMonitor(sim, feet, sites=G1_FEET).attach()
    assert monitor.contacts == {} and monitor.site_positions_W == {}  # nothing sampled yet
    sim.step()
    ref = _forces_per_contact(m, sim.data, feet)
    assert monitor.group_names == G1_FEET and monitor.site_names == G1_FEET
    for name, sums in zip(monitor.group_names, monitor.contact_sums, strict=True):
        f_ref, m_ref, n_ref, _ = ref[name]
        scale = max(np.linalg.norm(f_ref), 1e-300)
        np.testing.assert_allclose(sums[:3], f_ref, rtol=1e-9, atol=1e-9 * scale)
        np.testing.assert_allclose(sums[3:5], m_ref, rtol=1e-9, atol=1e-9 * scale)
        assert sums[5] == n_ref
        measured = monitor.contacts[name]  # the same numbers, as a MeasuredContact
        np.testing.assert_array_equal(measured.force_W, sums[:3])
        assert measured.n_contacts == n_ref
    left, right = (ref[f][2] for f in G1_FEET)
    assert (left, right) == ((4, 4) if lift_rad == 0 else (0, 4))  # each foot's 4 sole spheres
    ankles = ("left_ankle_roll_link", "right_ankle_roll_link")
    assert monitor.floor_bodies == (ankles if lift_rad == 0 else ankles[1:])
    assert np.isnan(monitor.contacts["left_foot"].cop_W).all() == (lift_rad > 0)
    assert monitor.contacts["right_foot"].normal_n > 100  # the robot's ~330 N weight and more
    fz = ref["right_foot"][0][2]
    np.testing.assert_allclose(monitor.contacts["right_foot"].cop_W[:2], ref["right_foot"][1] / fz, rtol=1e-9)
    # the sole spheres touch the floor at heights a fraction of a millimetre apart: within a micrometre
    np.testing.assert_allclose(monitor.contacts["right_foot"].cop_W[:2], ref["right_foot"][3] / fz, atol=1e-6)
    np.testing.assert_array_equal(monitor.site_array_W, sim.data.site_xpos[[g1.site_id(f) for f in G1_FEET]])
    np.testing.assert_array_equal(monitor.site_positions_W["right_foot"], monitor.site_array_W[1])
    np.testing.assert_allclose(monitor.com_W, bodies_com(m, sim.data, g1.robot_body_ids), rtol=1e-12)


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
    """Standing, folding onto its seat, sensors off a while: equal to the geom pairs' answer every step."""
    counted = add_floor_sensors(stool, FEET)
    sim = Simulator(counted)
    monitor = PlantMonitor(sim).attach()
    assert monitor._read is not None  # the counts serve this robot
    m, d = sim.model, sim.data
    pairs = FloorContacts(m, np.flatnonzero(m.geom_bodyid == 0), bodies=counted.robot_body_ids)
    seen, from_pairs = set(), 0
    sim.send(torque([0.0, 0.0, 0.0]))
    for k in range(900):
        if k == 150:  # the hips fold: the seat reaches the floor (from step ~485)
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
    assert {("foot_b", "foot_c", "seat"), ("seat",)} <= seen  # the counts disagree: the pairs answer
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
