"""The control loop's bounded log: decimated rows, and sums over every cycle that stay exact."""

from __future__ import annotations

import numpy as np
import pytest

from mbctl.control import loop
from mbctl.control.controller import joint_reference
from mbctl.control.exceptions import ControlError
from mbctl.control.gains import gains_from_frequency
from mbctl.control.loop import LOG_BATCH, log_rows, log_stride, run
from mbctl.control.pd import JointPD
from mbctl.planners.trajectory import JointTrajectory
from mbctl.sim.simulator import Simulator

CYCLES = 501  # 2 ms each on the 2-link arm


def _trajectory() -> JointTrajectory:
    t = np.arange(5) * 0.1
    return JointTrajectory(t, np.c_[0.5 * t, -t], np.c_[0.5 * np.ones(5), -np.ones(5)], np.zeros((5, 2)),
                           ("shoulder", "elbow"))


def _run(robot, reference, on_step=None):
    sim = Simulator(robot)
    sim.reset(q=[0.1, -0.2])
    controller = JointPD(robot, gains_from_frequency(20.0, 0.7, 0.1))
    return run(sim, controller, reference, CYCLES * sim.control_period_s, on_step), controller


def _check_stats(stats, q, v, command, error):
    for part, full in ((stats.q, q), (stats.v, v), (stats.command, command), (stats.error, error)):
        assert part.count == len(full)
        np.testing.assert_array_equal(part.min, full.min(axis=0))
        np.testing.assert_array_equal(part.max, full.max(axis=0))
        np.testing.assert_allclose(part.sum, full.sum(axis=0), rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(part.sum_sq, (full**2).sum(axis=0), rtol=1e-12)
    np.testing.assert_allclose(stats.error.rms_all(), np.sqrt(np.mean(error**2)), rtol=1e-12)
    np.testing.assert_allclose(stats.error.rms(), np.sqrt(np.mean(error**2, axis=0)), rtol=1e-12)
    np.testing.assert_array_equal(stats.q.max_abs(q[0]), np.abs(q - q[0]).max(axis=0))


def test_a_capped_log_keeps_every_stride_th_cycle_and_the_last_and_exact_stats(two_link_torque, monkeypatch):
    full, controller = _run(two_link_torque, _trajectory())
    assert full.stride == 1 and full.rows == full.cycles == CYCLES
    np.testing.assert_array_equal(full.cycle, np.arange(CYCLES))
    error = full.reference - full.q[:, controller.joint_map.idx_q]
    _check_stats(full.stats, full.q, full.v, full.command, error)

    monkeypatch.setattr(loop, "MAX_LOG_ROWS", 50)
    monkeypatch.setattr(loop, "SAMPLE_CHUNK", 64)  # the trajectory sampled in 8 chunks
    monkeypatch.setattr(loop, "LOG_BATCH", 37)  # written 37 cycles at a time: not the stride's multiple
    capped, _ = _run(two_link_torque, _trajectory())
    assert capped.stride == 11 and capped.cycles == CYCLES  # ceil(500 / 49)
    expected = np.r_[np.arange(0, CYCLES, 11), CYCLES - 1]  # 0, 11, ..., 495, and the last, 500
    np.testing.assert_array_equal(capped.cycle, expected)
    assert capped.rows == 47 <= 50
    for name in ("q", "v", "command", "reference", "reference_v"):
        np.testing.assert_array_equal(getattr(capped, name), getattr(full, name)[expected], err_msg=name)
    np.testing.assert_array_equal(capped.t_s, full.t_s)  # times and ticks: every cycle
    np.testing.assert_array_equal(capped.tick, full.tick)
    np.testing.assert_array_equal(capped.row_time_s, full.t_s[expected])
    # the capped run's sums are those of every cycle of the full-rate one
    _check_stats(capped.stats, full.q, full.v, full.command, error)


def test_a_run_ended_by_its_callback_keeps_its_last_cycle(two_link_torque, monkeypatch):
    full, _ = _run(two_link_torque, joint_reference([0.3, 0.1]))
    monkeypatch.setattr(loop, "MAX_LOG_ROWS", 50)
    log, controller = _run(two_link_torque, joint_reference([0.3, 0.1]), lambda k, *_: k == 300)
    assert log.cycles == 301 and log.stride == 11
    np.testing.assert_array_equal(log.cycle, np.r_[np.arange(0, 301, 11), 300])
    assert log.stats.q.count == 301
    np.testing.assert_array_equal(log.q[-1], full.q[300])
    error = 0.0 + np.array([0.3, 0.1]) - full.q[:301][:, controller.joint_map.idx_q]
    _check_stats(log.stats, full.q[:301], full.v[:301], full.command[:301], error)


def test_a_task_or_no_joint_reference_has_no_error_stats(two_link_torque):
    log, _ = _run(two_link_torque, lambda t: joint_reference([0.3, 0.1]))
    assert log.stats.error is not None  # a function giving joint references: its error is summed
    from mbctl.control.controller import task_reference
    from mbctl.control.task_space import TaskSpaceComputedTorque

    sim = Simulator(two_link_torque)
    sim.reset(q=[0.3, 0.6])
    log = run(sim, TaskSpaceComputedTorque(two_link_torque, gains_from_frequency(10.0)),
              task_reference([0.4, 0.3]), 0.01)
    assert log.stats.error is None and log.stats.q.count == 5


@pytest.mark.parametrize("n", [1, 2, 49, 50, 51, 99, 100, 101, 500, 501, 10_000, 1_800_001])
def test_the_stride_keeps_at_most_max_rows(n):
    stride = log_stride(n, 50)
    assert log_rows(n, stride) <= 50
    assert (stride == 1) == (n <= 50)
    assert log_rows(n, stride) == len(set(range(0, n, stride)) | {n - 1})


def test_a_row_cap_below_two_is_refused():
    with pytest.raises(ControlError, match="max_rows must be >= 2 .*got 1"):
        log_stride(10, 1)


def test_a_reference_function_that_reuses_its_buffers_is_logged_cycle_by_cycle(two_link_torque):
    """The log writes its cycles in batches: a reference handed out again and changed is copied first."""
    q_ref, v_ref, a_ref = np.zeros(2), np.zeros(2), np.zeros(2)

    def reference(t: float):
        q_ref[:] = (0.3 * t, -0.2 * t)  # the same arrays every cycle, new values
        v_ref[:] = (0.3, -0.2)
        return joint_reference(q_ref, v_ref, a_ref)._replace(q=q_ref, v=v_ref)

    log, _ = _run(two_link_torque, reference)
    t = log.t_s - log.t_s[0]
    np.testing.assert_array_equal(log.reference, np.column_stack([0.3 * t, -0.2 * t]))
    assert log.cycles == CYCLES > LOG_BATCH


def test_a_log_without_rows_keeps_every_cycles_time_and_tick_and_no_sums(two_link_torque):
    """``rows=False``: the times and ticks of every cycle, no rows, and sums() says why there are none."""
    sim = Simulator(two_link_torque)
    sim.reset(q=[0.1, -0.2])
    controller = JointPD(two_link_torque, gains_from_frequency(20.0, 0.7, 0.1))
    log = run(sim, controller, _trajectory(), CYCLES * sim.control_period_s, rows=False)
    full, _ = _run(two_link_torque, _trajectory())
    assert log.cycles == CYCLES and log.rows == 0 and log.q.shape == (0, two_link_torque.nq)
    np.testing.assert_array_equal(log.t_s, full.t_s)
    np.testing.assert_array_equal(log.tick, full.tick)
    assert np.unique(np.diff(log.tick)).tolist() == [1]
    with pytest.raises(ControlError, match=r"run\(rows=False\), which keeps only the cycles' times"):
        log.sums()
