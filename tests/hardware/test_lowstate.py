"""What the DDS interface takes from a robot's state stream: CRC, order, rate, bad values, and what it says.

Against a fake G1 on loopback (tests/hardware/conftest.py) that can leave its CRC 0 and its tick
still (as Unitree's simulator does), publish at another rate, or send one odd message.
"""

from __future__ import annotations

import numpy as np
import pytest

from mbctl.control.loop import run
from mbctl.hardware import DdsOptions, LinkLost, NoRobotError, UnitreeG1
from mbctl.hardware.lowstate import ORDER_ARRIVAL, ORDER_TICK, LowStateStream
from mbctl.unitree.wire import low_state_codec
from tests.hardware.test_unitree_g1 import HOLD, ConstantTorque, StillBase, _wait_for


def _open(g1, dds_domain, **options):
    return UnitreeG1(g1, StillBase(), DdsOptions(**{"domain": dds_domain, "watchdog_periods": 50, **options}))


def test_nothing_on_the_domain_is_said(g1, dds_domain):
    with pytest.raises(NoRobotError, match="nothing was seen on the domain"):
        _open(g1, dds_domain, connect_timeout_s=0.3)


def test_unsigned_states_need_the_opt_in_and_the_error_names_it(g1, fake_g1, dds_domain):
    fake_g1(unsigned=True)
    with pytest.raises(NoRobotError, match=r"(\d+) with a bad CRC \(\1 with CRC 0: unsigned, as Unitree's "
                                           r"simulator sends them; `--state-crc off` accepts those\)"):
        _open(g1, dds_domain, connect_timeout_s=0.5)
    with _open(g1, dds_domain, check_state_crc=False) as robot:
        run(robot, ConstantTorque(g1), HOLD, 0.02)
        link = robot.report().link
    assert link.crc_unchecked >= 26 + 10 and link.bad_crc == 0  # connect's states and the loop's


def test_a_wrong_crc_is_refused_even_when_crc_0_is_accepted(g1, fake_g1, dds_domain):
    fake_g1(bad_crc=True)
    with pytest.raises(NoRobotError, match=r"(\d+) LowState messages seen, \1 with a bad CRC \(needs"):
        _open(g1, dds_domain, connect_timeout_s=0.5, check_state_crc=False)


def test_a_tick_of_0_orders_states_by_arrival(g1, fake_g1, dds_domain):
    fake_g1(tick_step=0, tick0=0)  # as Unitree's simulator: the same bytes each time, still new states
    with _open(g1, dds_domain) as robot:
        log = run(robot, ConstantTorque(g1), HOLD, 0.04)
        report = robot.report()
    assert report.link.state_order == ORDER_ARRIVAL and log.cycles == 20
    assert report.link.states_superseded == 0 and report.values()["state_order"] == "arrival"
    assert np.all(np.diff(log.t_s) > 0)  # each cycle a state that arrived later


def test_a_tick_that_stays_is_one_state_held_and_the_loss_says_so(g1, fake_g1, dds_domain):
    """A non-zero tick that never advances: a robot held still connects, then the loop sees nothing new."""
    fake_g1(tick_step=0)
    with _open(g1, dds_domain, watchdog_periods=3) as robot:
        assert robot.control_period_s == 0.002  # its repeats come at its rate
        with pytest.raises(LinkLost, match=r"1 valid, (\d+) that never advance \(their tick not past \d+: 0 "
                                           r"behind, \1 the same\)"):
            run(robot, ConstantTorque(g1), HOLD, 1.0)


def test_a_tick_running_backwards_never_advances_and_is_no_robot(g1, fake_g1, dds_domain):
    fake_g1(tick_step=-1)
    with pytest.raises(NoRobotError, match=r"1 valid, (\d+) that never advance \(their tick not past \d+: \1 "
                                           r"behind, 0 the same\)"):
        _open(g1, dds_domain, connect_timeout_s=0.3)


def test_the_rate_is_measured_at_connect_and_paces_the_loop_and_the_watchdog(g1, fake_g1, dds_domain):
    fake_g1(period_s=0.005)  # Unitree's simulator publishes at 200 Hz
    with _open(g1, dds_domain, watchdog_periods=3) as robot:
        assert robot.control_period_s == 0.005
        log = run(robot, ConstantTorque(g1), HOLD, 0.05)
        assert log.cycles == 10 and robot.report().link.state_rate_hz == pytest.approx(200.0)
        # the robot's clock: tick steps times the period, not when this process read them
        np.testing.assert_allclose(np.diff(log.t_s), 0.005 * np.diff(log.tick), rtol=0, atol=1e-12)
    with _open(g1, dds_domain, rate_hz=250.0) as robot:  # given: not measured
        assert robot.control_period_s == 0.004


def test_a_bad_imu_quaternion_is_a_counted_bad_state(g1, fake_g1, dds_domain):
    fake = fake_g1()
    with _open(g1, dds_domain) as robot:
        for n, bad in enumerate(((0.0, 0.0, 0.0, 0.0), (np.nan, 0.0, 0.0, 1.0), (0.9, 0.0, 0.0, 0.0)), 1):
            fake.once(quaternion=bad)
            assert _wait_for(lambda n=n: robot.read_state() is not None
                             and robot.report().link.bad_states == n)
        state = robot.read_state()
        assert np.isfinite(state.q).all() and robot.report().link.bad_states == 3


def test_only_bad_quaternions_is_no_robot_naming_the_values(g1, fake_g1, dds_domain):
    fake_g1(quat_wxyz=(0.0, 0.0, 0.0, 0.0))
    with pytest.raises(NoRobotError, match=r"(\d+) LowState messages seen, \1 with bad values \(IMU "
                                           r"quaternion"):
        _open(g1, dds_domain, connect_timeout_s=0.3)


def test_a_spoofed_tick_is_a_bad_state_not_the_new_clock(g1, fake_g1, dds_domain):
    fake = fake_g1()
    with _open(g1, dds_domain) as robot:
        run(robot, ConstantTorque(g1), HOLD, 0.01)
        fake.once(tick=2**32 - 1)
        assert _wait_for(lambda: robot.read_state() is not None and robot.report().link.bad_states == 1)
        tick = robot.read_state().tick
        log = run(robot, ConstantTorque(g1), HOLD, 0.02)  # the clock goes on from the real ticks
        report = robot.report()
    assert tick < 2**31 and log.tick[-1] < 2**31 and np.all(np.diff(log.tick) > 0)
    assert report.link.state_order == ORDER_TICK and report.link.bad_states == 1


class _NoReader:
    """A reader that never has anything: the tests below hand the stream each state themselves."""

    def take(self, max_samples=16):
        return []


def _state(tick):
    """A valid LowState_ (wire bytes) of a robot at rest with ``tick``."""
    codec = low_state_codec()
    codec.message["tick"] = tick
    codec.message["imu_state"]["quaternion"] = (1.0, 0.0, 0.0, 0.0)
    return codec.encode()


def _feed(stream, ticks_at):
    """Give ``stream`` a state of each (tick, arrival time [s]); whether each became the newest."""
    return [stream._take(_state(tick), now) for tick, now in ticks_at]


def test_a_spoofed_tick_while_connecting_is_refused_and_the_real_stream_goes_on():
    """Before the rate is measured the bound counts periods at the fastest accepted rate (2 kHz)."""
    stream = LowStateStream(_NoReader(), 29)
    taken = _feed(stream, [(100, 0.0), (101, 0.002), (102, 0.004), (2**32 - 1, 0.005), (103, 0.006)])
    assert taken == [True, True, True, False, True] and stream.tick == 103
    assert stream.counts.bad_states == stream.counts.far_ticks == 1
    assert "1 with a tick further ahead of the newest (103) than the time since it allows" in (
        stream.diagnosis())


def test_a_spoofed_tick_on_a_held_robot_is_refused_though_its_step_is_not_known():
    """A robot held still (one tick repeated) has no step yet: its first advance is bounded by time."""
    stream = LowStateStream(_NoReader(), 29)
    held = [(7, 0.002 * k) for k in range(5)]
    assert _feed(stream, held) == [True, False, False, False, False]
    assert _feed(stream, [(2**32 - 1, 0.010), (8, 0.012), (9, 0.014)]) == [False, True, True]
    assert stream.counts.far_ticks == 1 and stream.counts.repeated == 4 and stream.tick == 9


def test_ticks_the_time_explains_are_taken():
    """A microsecond-like first step, and a gap after a stall the elapsed time explains, are new states."""
    stream = LowStateStream(_NoReader(), 29)
    assert _feed(stream, [(0 + 1, 0.0), (2001, 0.002), (4001, 0.004)]) == [True, True, True]
    stream.start_clock(0.002)
    # 1 s without a state (a stalled process): 500 periods, 500 steps of 2000 ticks
    assert _feed(stream, [(4001 + 500 * 2000, 1.004)]) == [True]
    assert stream.counts.bad_states == 0


def test_in_arrival_order_the_time_counts_states_at_the_period_not_their_arrivals():
    """Tick 0 (Unitree's simulator): from connect, n new states are n periods, however they arrive;
    the first advancing tick ends that clock (its arrival until the tick's step is known)."""
    stream = LowStateStream(_NoReader(), 29)
    _feed(stream, [(0, 0.0), (0, 0.005), (0, 0.010)])
    assert stream.order == "arrival" and stream.time_s == pytest.approx(0.010)  # arrivals, connecting
    stream.start_clock(0.005)
    assert _feed(stream, [(0, 0.019), (0, 0.020), (0, 0.041)]) == [True, True, True]  # stalls, a burst
    assert stream.time_s == pytest.approx(0.010 + 3 * 0.005)
    assert _feed(stream, [(5, 0.046)]) == [True] and stream.order == "tick"
    assert stream.time_s == pytest.approx(0.046)


def test_a_spoofed_tick_on_a_held_robot_does_not_become_its_clock(g1, fake_g1, dds_domain):
    """As ``mbctl serve g1 --lockstep`` before the first command: the tick held, then it advances."""
    fake = fake_g1(tick_step=0)
    with _open(g1, dds_domain) as robot:
        fake.once(tick=2**32 - 1)
        assert _wait_for(lambda: (robot.stream.drain(), robot.stream.counts.bad_states)[1] == 1)
        with fake._lock:  # the robot starts: its tick advances from the held one
            fake._tick_step = 1
        log = run(robot, ConstantTorque(g1), HOLD, 0.02)
        report = robot.report()
    assert log.cycles == 10 and log.tick[-1] < 2**31 and np.all(np.diff(log.tick) > 0)
    assert report.link.bad_states == 1 and report.link.state_order == ORDER_TICK


def test_the_cli_s_defaults_are_the_interface_s():
    """The help shows the defaults without importing numpy: its copies must be the interface's."""
    from mbctl.cli import plant_options
    from mbctl.hardware import dds_options

    assert plant_options.WATCHDOG_PERIODS == dds_options.WATCHDOG_PERIODS
    assert plant_options.CONNECT_TIMEOUT_S == dds_options.CONNECT_TIMEOUT_S
