"""Contact forces measured in the plant, and pushes, on a box built in code."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from mbctl.sim.contacts import measure_contacts, touching
from mbctl.sim.exceptions import SimError
from mbctl.sim.perturb import Push, PushSchedule

BOX = """
<mujoco>
  <option timestep="0.002"/>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    <body name="box" pos="0.3 -0.2 0.1">
      <freejoint/>
      <geom name="c0" type="sphere" size="0.01" pos="0.1 0.05 -0.09" mass="0.5"/>
      <geom name="c1" type="sphere" size="0.01" pos="0.1 -0.05 -0.09" mass="0.5"/>
      <geom name="c2" type="sphere" size="0.01" pos="-0.1 0.05 -0.09" mass="0.5"/>
      <geom name="c3" type="sphere" size="0.01" pos="-0.1 -0.05 -0.09" mass="0.5"/>
      <geom name="top" type="box" size="0.1 0.05 0.01" pos="0.05 0 0.05" mass="1.0"
            contype="0" conaffinity="0"/>
    </body>
    <body name="ball" pos="1 1 0.3"><freejoint/><geom type="sphere" size="0.05" mass="0.1"/></body>
  </worldbody>
</mujoco>
"""


def _settled():
    m = mujoco.MjModel.from_xml_string(BOX)
    d = mujoco.MjData(m)
    mujoco.mj_step(m, d, 1500)
    return m, d


def test_measured_force_carries_the_weight_and_the_cop_is_under_the_com():
    m, d = _settled()
    feet = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, f"c{i}") for i in range(4)]
    out = measure_contacts(m, d, {"box": feet})["box"]
    box = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "box")
    assert out.n_contacts == 4
    assert out.normal_n == pytest.approx(3.0 * 9.81, rel=1e-3)
    assert out.tangential_n < 1e-6
    np.testing.assert_allclose(out.cop_W[:2], d.xipos[box][:2], atol=1e-4)  # the CoM is off-centre
    assert abs(d.xipos[box][0] - 0.3) > 0.01


def test_touching_names_bodies_other_than_the_allowed_geoms():
    m, d = _settled()
    floor = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "floor")]
    feet = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, f"c{i}") for i in range(4)]
    assert touching(m, d, floor, feet) == ["ball"]
    assert touching(m, d, floor, feet + [m.ngeom - 1]) == []


def test_push_gives_its_impulse():
    m = mujoco.MjModel.from_xml_string(BOX)
    d = mujoco.MjData(m)
    m.opt.gravity[:] = 0.0
    m.geom_contype[:] = 0
    schedule = PushSchedule(m, [Push("box", (30.0, 0.0, 0.0), 0.1, 0.1)])
    assert schedule.pushes[0].impulse_n_s == pytest.approx(3.0)
    while d.time < 0.4:
        schedule.apply(d)
        mujoco.mj_step(m, d)
    # 3 N s on the 3 kg box: 1 m/s (the free joint's linear velocity, world frame)
    assert d.qvel[0] == pytest.approx(1.0, rel=1e-6)
    with pytest.raises(SimError, match="push on unknown body 'nope'"):
        PushSchedule(m, [Push("nope", (1.0, 0.0, 0.0), 0.0, 0.1)])


STACK = """
<mujoco>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    <body name="low" pos="0 0 0.1">
      <freejoint/><geom name="low" type="box" size="0.1 0.1 0.1" mass="2"/>
    </body>
    <body name="up" pos="0 0 0.3">
      <freejoint/><geom name="up" type="box" size="0.05 0.05 0.1" mass="0.5"/>
    </body>
  </worldbody>
</mujoco>
"""


def test_a_contact_between_two_groups_counts_for_both_with_opposite_signs():
    from mbctl.sim.contacts import ContactSensor, FloorContacts

    m = mujoco.MjModel.from_xml_string(STACK)
    d = mujoco.MjData(m)
    mujoco.mj_step(m, d, 1000)
    low, up = (mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, n) for n in ("low", "up"))
    out = ContactSensor(m, {"low": [low], "up": [up]}).measure(d)
    g = 9.81
    assert out["up"].normal_n == pytest.approx(0.5 * g, rel=1e-3)  # the lower box holds the upper
    assert out["low"].normal_n == pytest.approx(2.0 * g, rel=1e-3)  # floor (2.5 g) minus the upper (0.5 g)
    floor = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "floor")]
    assert FloorContacts(m, floor).bodies(d) == ["low"]
    up_body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "up")
    assert FloorContacts(m, floor, bodies=[up_body]).bodies(d) == []


def test_contact_wrenches_and_contacts_elsewhere():
    """A 2 kg box resting on the floor: the floor pushes m g up, with no moment about its centre."""
    import mujoco
    import numpy as np

    from mbctl.sim.contacts import contact_wrenches, contacts_elsewhere

    m = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><geom name="floor" type="plane" size="1 1 0.1"/><body name="box" pos="0 0 0.05">'
        '<freejoint/><geom name="b" type="box" size="0.05 0.05 0.05" mass="2"/></body><body name="ball" '
        'pos="0.3 0 0.05"><freejoint/><geom name="s" type="sphere" size="0.05" mass="1"/></body></worldbody>'
        "</mujoco>")
    d = mujoco.MjData(m)
    for _ in range(500):
        mujoco.mj_step(m, d)
    box = m.body("box").id
    box_geom = m.geom("b").id
    touching, wrench = contact_wrenches(m, d, [[box_geom]], d.xpos[[box]])
    assert touching.tolist() == [True]
    np.testing.assert_allclose(wrench[0, :3], [0, 0, 2 * 9.81], atol=1e-2)
    np.testing.assert_allclose(wrench[0, 3:], 0.0, atol=1e-3)
    assert contacts_elsewhere(m, d, [box, m.body("ball").id], [box_geom]) == 1  # the ball on the floor
