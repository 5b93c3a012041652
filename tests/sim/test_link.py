"""The link model: delays, drops and reordering, and the in-process simulator seen through it."""

from __future__ import annotations

import numpy as np
import pytest

from mbctl.robots.commands import torque
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


@pytest.mark.parametrize(("field", "value"), [("latency_ms", -1.0), ("drop", 1.0), ("imu_noise", np.nan)])
def test_bad_link_numbers_are_named(field, value):
    with pytest.raises(SimError, match=field):
        LinkSpec(**{field: value})


def test_latency_delays_commands_and_states_by_whole_steps(two_link_torque):
    sim = Simulator(two_link_torque)
    dt = sim.control_period_s
    linked = LinkedSimulator(sim, LinkSpec(latency_ms=2 * dt * 1e3))  # two steps each way
    t0 = linked.read_state().time_s
    linked.send(torque(np.ones(sim.robot.nu)))
    for k in range(3):
        assert (sim.ctrl == 0).all() or k == 2  # delivered at the third step's start
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
