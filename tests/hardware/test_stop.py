"""The end of a loop on the DDS interface: the damping command every period until ``close()``.

``control.loop.run`` calls ``stop()`` however the loop ends; from then on a thread sends the
damping command each period while the job writes its results, until the interface is closed (or
a new command resumes). Watched on the wire, at a fake G1 (tests/hardware/conftest.py).
"""

from __future__ import annotations

import time

import numpy as np
import pytest

from mbctl.control.loop import run
from mbctl.hardware import DdsOptions, UnitreeG1
from mbctl.robots.commands import torque
from tests.hardware.test_unitree_g1 import HOLD, ConstantTorque, StillBase, _is_damping, _wait_for
from tests.hardware.wire_tap import WireTap, after_the_loop

#: Damping commands watched after the loop (0.1 s at 500 Hz).
WATCHED = 50


def damping_after(fake, n_before: int, g1) -> tuple[list[bool], np.ndarray]:
    """Whether each command after the first ``n_before`` is damping, and the gaps [s] between them."""
    commands, times = fake.commands[n_before:], np.array(fake.command_times[n_before:])
    return [_is_damping(c, g1) for c in commands], np.diff(times)


def assert_damping_at_the_period(damped: list[bool], gaps_s: np.ndarray, period_s: float) -> None:
    assert len(damped) >= WATCHED and all(damped)
    # each period one: the keeper's own clock (the median: a loaded machine delays a few)
    assert np.median(gaps_s) == pytest.approx(period_s, rel=0.25)


def test_damping_goes_out_every_period_from_the_end_of_the_loop_until_close(g1, fake_g1, dds_domain):
    fake = fake_g1()
    robot = UnitreeG1(g1, StillBase(), DdsOptions(domain=dds_domain, watchdog_periods=50))
    try:
        log = run(robot, ConstantTorque(g1), HOLD, 0.04)
        n_loop = log.cycles  # one command per cycle, then the keeper's
        assert _wait_for(lambda: len(fake.commands) >= n_loop + WATCHED)
        assert not any(_is_damping(c, g1) for c in fake.commands[:n_loop])
        damped, gaps = damping_after(fake, n_loop, g1)
        assert_damping_at_the_period(damped, gaps, 0.002)
        assert robot.report().safety.damped is True
    finally:
        robot.close()
    time.sleep(0.02)  # the fake takes what is in flight
    n_closed = len(fake.commands)
    time.sleep(0.05)
    assert len(fake.commands) == n_closed  # closed: nothing more


def test_an_exception_in_the_loop_starts_the_damping_too(g1, fake_g1, dds_domain):
    fake = fake_g1()
    with UnitreeG1(g1, StillBase(), DdsOptions(domain=dds_domain, watchdog_periods=50)) as robot:
        with pytest.raises(RuntimeError):
            run(robot, ConstantTorque(g1, stop_at=5, stop_with=RuntimeError), HOLD, 1.0)
        assert _wait_for(lambda: len(fake.commands) >= 4 + WATCHED)
        damped, gaps = damping_after(fake, 4, g1)
        assert_damping_at_the_period(damped, gaps, 0.002)


def test_a_new_command_after_the_loop_resumes_and_a_dry_run_sends_nothing(g1, fake_g1, dds_domain):
    fake = fake_g1()
    with UnitreeG1(g1, StillBase(), DdsOptions(domain=dds_domain, watchdog_periods=50)) as robot:
        run(robot, ConstantTorque(g1), HOLD, 0.01)
        robot.send(torque({"left_knee_joint": 1.0}))  # the keeper stops first
        assert _wait_for(lambda: any(c["tau"][3] == 1.0 for c in fake.commands))
        time.sleep(0.05)
        resumed = next(i for i, c in enumerate(fake.commands) if c["tau"][3] == 1.0)
        assert not any(_is_damping(c, g1) for c in fake.commands[resumed:])  # nothing damps it meanwhile
    time.sleep(0.02)
    n_closed = len(fake.commands)  # the last: close()'s damping
    with UnitreeG1(g1, StillBase(), DdsOptions(domain=dds_domain, dry_run=True)) as robot:
        robot.read_state()
        robot.stop()
        time.sleep(0.02)
        assert robot.report().safety.damped is None
    time.sleep(0.02)
    assert len(fake.commands) == n_closed


def watch_the_wire_after_the_loop(g1, domain: int, options: DdsOptions, period_s: float) -> None:
    """A loop against a plant, then the wire until close(): only damping, at ``period_s``, while open."""
    # the tap after the client connected: the client waited for the plant's reader itself
    with UnitreeG1(g1, StillBase(), options) as robot, WireTap(domain) as tap:
        assert tap.wait_matched()
        log = run(robot, ConstantTorque(g1), HOLD, 0.1)
        # the loop ran, paced by the plant's states at its period (the rate measured at connect); how
        # many cycles fit in 0.1 s is the plant's pace under load (Unitree's simulator: its arrivals on
        # the wall clock; 16 of 20 once on a loaded CI run), not asserted
        assert log.cycles >= 2
        assert robot.report().link.state_rate_hz == pytest.approx(1.0 / period_s)
        assert tap.wait_for(log.cycles + WATCHED)
        damped, gaps = after_the_loop(tap, g1)
    assert_damping_at_the_period(damped, gaps, period_s)


def test_after_the_loop_damping_reaches_mbctl_s_bridge_every_period(g1, dds_domain, tmp_path):
    from tests.jobs.test_dds_jobs import bridge

    with bridge(dds_domain, tmp_path / "serve") as proc:
        options = DdsOptions(domain=dds_domain, watchdog_periods=500)
        watch_the_wire_after_the_loop(g1, dds_domain, options, 0.002)
        assert proc.poll() is None
