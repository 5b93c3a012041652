"""The link model: delays, drops and reordering, and the in-process simulator seen through it."""

from __future__ import annotations

import numpy as np
import pytest

from mbctl.robots.commands import torque
from mbctl.robots.interface import ImuSpec
from mbctl.robots.registry import load_robot
from mbctl.sim.exceptions import SimError
from mbctl.sim.link import DelayLine, LinkedSimulator, LinkSpec
from mbctl.sim.simulator import Simulator


def test_a_message_arrives_after_the_latency_and_the_newest_wins():
    line = DelayLine(LinkSpec(latency_ms=5.0), np.random.default_rng(0))
    line.send(0.000, "a")
    line.send(0.001, "b")
    assert line.receive(0.0049) is None
    assert line.receive(0.0061) == "b" and line.superseded == 1  # "a" arrived too, older
    assert line.receive(0.1) is None


class Draws:
    """A random source returning given numbers (the jitter fractions of successive messages)."""

    def __init__(self, *values):
        self.values = iter(values)

    def random(self):
        return next(self.values)


def test_an_older_message_arriving_late_is_discarded():
    line = DelayLine(LinkSpec(jitter_ms=10.0), Draws(0.9, 0.1))  # "old" takes 9 ms, "new" 1 ms
    line.send(0.0, "old")
    line.send(0.0, "new")
    assert line.receive(0.005) == "new"
    assert line.receive(0.020) is None  # "old" arrived after "new": the receiver keeps "new"
    assert line.superseded == 1


def test_drops_happen_at_the_given_rate():
    line = DelayLine(LinkSpec(drop=0.2, seed=1), np.random.default_rng(1))
    for k in range(5000):
        line.send(k * 0.002, k)
    assert 0.17 < line.dropped / 5000 < 0.23


@pytest.mark.parametrize(("field", "value"), [("latency_ms", -1.0), ("drop", 1.0), ("imu_noise", np.nan),
                                              ("seed", -1)])
def test_bad_link_numbers_are_named(field, value):
    with pytest.raises(SimError, match=field):
        LinkSpec(**{field: value})


def test_latency_delays_commands_and_states_by_whole_steps(two_link_torque):
    sim = Simulator(two_link_torque)
    dt = sim.control_period_s
    linked = LinkedSimulator(sim, LinkSpec(latency_ms=2 * dt * 1e3))  # two steps each way
    t0 = linked.read_state().time_s
    linked.send(torque(np.ones(sim.robot.nu)))
    for _ in range(3):  # delivered at the start of the third sync: not before it
        assert (sim.ctrl == 0).all()
        linked.sync()
    assert (sim.ctrl == 1).all()
    assert linked.read_state().time_s == pytest.approx(sim.time_s - 2 * dt)
    assert linked.read_state().time_s > t0


def test_ideal_link_is_the_plant(two_link_torque):
    a, b = Simulator(two_link_torque), Simulator(two_link_torque)
    linked = LinkedSimulator(b, LinkSpec())
    for _ in range(20):
        a.send(torque(np.array([0.1, -0.2])))
        linked.send(torque(np.array([0.1, -0.2])))
        a.sync()
        linked.sync()
        assert np.array_equal(a.read_state().q, linked.read_state().q)


def test_an_estimator_needs_the_imu(two_link_torque):
    with pytest.raises(SimError, match="needs the robot's IMU"):
        LinkedSimulator(Simulator(two_link_torque), LinkSpec(imu_noise=1.0))


# A one-legged hopper standing on its foot: a free torso with a rotated IMU site and a motor at the
# hip. Uncommanded, gravity folds the hip and the torso sags.
HOPPER = """<mujoco><option timestep="0.002"/>
  <worldbody><geom name="floor" type="plane" size="2 2 0.1"/>
    <body name="torso" pos="0 0 0.399"><freejoint name="root"/>
      <geom type="box" size="0.1 0.05 0.05" mass="4"/>
      <site name="imu" euler="10 -20 30"/>
      <body name="leg" pos="0.05 0 -0.05"><joint name="hip" type="hinge" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0.1 0 -0.33" size="0.02" mass="1"/>
      </body>
    </body>
  </worldbody>
  <actuator><motor name="hip" joint="hip"/></actuator>
  <sensor><gyro name="gyro" site="imu"/><accelerometer name="accel" site="imu"/></sensor>
</mujoco>"""
HOPPER_IMU = ImuSpec("imu", "gyro", "accel")


@pytest.fixture
def hopper(tmp_path):
    (tmp_path / "hopper.xml").write_text(HOPPER)
    return load_robot(tmp_path / "hopper.xml")


def test_the_plant_holds_still_until_the_first_command_arrives(hopper):
    """As the bridge's physics waits for its first LowCmd: no sag during the first 20 ms of latency."""
    sim = Simulator(hopper)
    q0 = sim.q
    linked = LinkedSimulator(sim, LinkSpec(latency_ms=20.0))
    hold = torque([5.0])
    for _ in range(10):  # 10 periods of 2 ms: the first command arrives at the start of the 11th
        linked.send(hold)
        linked.sync()
        assert np.array_equal(sim.q, q0) and not linked.started
        assert np.array_equal(linked.read_state().q, q0) and not linked.read_state().v.any()
    assert sim.time_s == pytest.approx(0.020) and sim.n_steps == 0  # its clock ran, no physics
    linked.send(hold)
    linked.sync()
    assert linked.started and sim.n_steps == 1 and (sim.ctrl == 5.0).all()
    assert not np.array_equal(sim.q, q0)
    assert linked.report().link.held_s == pytest.approx(0.020)
    # what the jobs judge "the controller acted" by: commands that reached the plant, and in which cycles
    link = linked.report().link
    assert (link.commands_applied, link.commanded_cycles, linked.cycles) == (1, 1, 11)


def test_the_link_counts_the_commands_that_reach_the_plant(hopper):
    """Every command dropped but a few: the plant knows how few reached it (and in how few cycles)."""
    linked = LinkedSimulator(Simulator(hopper), LinkSpec(drop=0.9, seed=3))
    for _ in range(200):
        linked.send(torque([1.0]))
        linked.sync()
    link = linked.report().link
    assert link.commands_applied == link.commanded_cycles == 200 - link.commands_lost
    assert 5 < link.commanded_cycles < 40  # ~10 % of 200
    assert linked.report().values()["commanded_cycles"] == link.commanded_cycles


def test_without_latency_the_plant_starts_with_the_first_command(hopper):
    sim = Simulator(hopper)
    linked = LinkedSimulator(sim, LinkSpec(imu_noise=1.0), imu=HOPPER_IMU)
    linked.send(torque([0.0]))
    linked.sync()
    assert linked.started and sim.n_steps == 1 and linked.report().link.held_s == 0.0


class Recorder:
    """A base-state estimator that keeps the readings it was given and reports the plant's base."""

    estimated = ("base_position",)

    def __init__(self, sim):
        self.sim, self.readings = sim, []

    def reset(self, reading):
        self.readings.append(reading)

    def update(self, reading):
        self.readings.append(reading)
        return self.sim.q[:7], self.sim.v[:6]


def test_a_held_plant_reports_its_imu_at_rest(hopper):
    """Held still, the IMU reads no rotation and the specific force -g in its own (rotated) frame."""
    sim = Simulator(hopper)
    estimator = Recorder(sim)
    linked = LinkedSimulator(sim, LinkSpec(latency_ms=6.0), estimator, HOPPER_IMU)
    for _ in range(3):
        linked.send(torque([0.0]))
        linked.sync()
    R_WI = sim.data.site_xmat[hopper.site_id("imu")].reshape(3, 3)
    at_rest_I = R_WI.T @ [0.0, 0.0, 9.81]
    assert abs(at_rest_I[2] - 9.81) > 0.5  # the site is rotated: not trivially (0, 0, g)
    # reset and the first state at t = 0, then one per held physics step until the command arrives
    assert [r.time_s for r in estimator.readings] == pytest.approx([0.0, 0.0, 0.002, 0.004, 0.006])
    for r in estimator.readings:
        assert not r.imu.gyro_I.any()
        np.testing.assert_allclose(r.imu.accel_I, at_rest_I, atol=1e-12)
    linked.send(torque([0.0]))
    linked.sync()  # the command arrived: the plant's own sensors, the uncommanded hip folding
    assert not np.allclose(estimator.readings[-1].imu.accel_I, at_rest_I, atol=1e-3)
