"""The wall-clock pacing of the real-time plants: deadlines, misses, and work timed in wall and CPU time."""

from __future__ import annotations

import time

from mbctl.unitree.clock import CycleClock


def _compute(cpu_s: float) -> None:
    """Spend ``cpu_s`` [s] of this thread's CPU time (however long a loaded machine makes it last)."""
    end = time.thread_time() + cpu_s
    while time.thread_time() < end:
        pass


def test_a_cycle_waiting_for_a_core_is_a_miss_but_not_a_cpu_overrun():
    """Work that overran in wall time only (a sleep stands for a preemption here) is told apart from
    work that computed past the period."""
    clock = CycleClock(0.004)
    clock.start()
    time.sleep(0.006)  # cycle 0: off the CPU for longer than the period
    clock.wait()
    _compute(0.006)  # cycle 1: computing past the period
    clock.wait()
    p = clock.stats()
    assert p.cycles == 3 and p.deadline_misses == 2
    assert p.cpu_overruns == 1
    assert p.work_p99_ms >= 5.9 and 5.9 <= p.work_cpu_p99_ms < 50


def test_a_loop_paced_by_its_input_marks_work_done_before_waiting():
    clock = CycleClock(0.002)
    clock.start()
    for _ in range(5):
        _compute(0.0003)
        overran = clock.work_done() > clock.deadline
        time.sleep(0.001)  # waiting for the next state: not work
        clock.mark(overran)
    p = clock.stats()
    assert p.cycles == 6 and p.cpu_overruns == 0
    assert 0.29 < p.work_cpu_p99_ms < 1.5
