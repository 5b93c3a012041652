"""g1-wbc's log of a long run: its plots' rows capped, every reported figure still over every cycle.

The cap (``MAX_LOG_ROWS``, 100,000 rows) is patched down to 20 rows so a 0.5 s run (250 cycles)
is a long one. The medians and 95th percentiles are of float32 inputs (7 significant digits).
"""

from __future__ import annotations

import math
from functools import partial

import numpy as np
import pytest

from mbctl.control.loop import log_rows, log_stride
from mbctl.jobs import g1_wbc, wbc_log
from mbctl.jobs.g1_wbc import WBCParams, prepare
from mbctl.jobs.log_sums import CoMErrorSums
from mbctl.jobs.plant import PlantOptions
from mbctl.jobs.runner import Job, run_job
from mbctl.jobs.wbc_log import SETTLE_S, WBCLog, WBCRecord, com_tracking_error
from tests.jobs.log_spy import spy_on_log

#: Figures that do not depend on the wall clock: the same in two runs of the deterministic plant.
PLANT_FIGURES = ("com_error_rms_m", "max_foot_slip_m", "contact_force_rel_error",
                 "contact_force_rel_error_p95", "contact_force_rel_error_max",
                 "contact_force_rel_error_settling_max", "pelvis_z_min_m", "qp_fast_path_fraction", "fell")


def _run(g1, folder, monkeypatch, cap=None, **kw):
    """Run g1-wbc; return the record, its log and every cycle's times [us] read from their sources."""
    if cap is not None:
        monkeypatch.setattr(wbc_log, "MAX_LOG_ROWS", cap)

    def times(log: WBCLog) -> tuple[float, float, float]:
        sol = log.wb.controller.solution
        return sol.controller_time_s * 1e6, sol.qp_time_s * 1e6, log.monitor.sim.physics_time_s * 1e6

    return spy_on_log(monkeypatch, WBCLog, lambda: run_job(Job("g1-wbc", partial(prepare, robot=g1)),
                      WBCParams(**kw), folder), times)


def _csv(path):
    names = path.read_text().splitlines()[0].split(",")
    rows = np.loadtxt(path, delimiter=",", skiprows=1)
    return {name: rows[:, i] for i, name in enumerate(names)}


def test_a_capped_log_keeps_20_rows_and_reports_every_cycles_figures(g1, tmp_path, monkeypatch):
    full, full_log, _ = _run(g1, tmp_path / "full", monkeypatch, scenario="stand", duration=0.5)
    capped, log, times = _run(g1, tmp_path / "capped", monkeypatch, cap=20, scenario="stand", duration=0.5)
    assert capped.exit_code == full.exit_code == 0
    # the plots' rows: every 14th cycle and the last (19 rows), the uncapped log every cycle
    assert (full_log.stride, full_log.rows) == (1, 250)
    assert (log.stride, log.rows) == (14, 19) == (log_stride(250, 20), log_rows(250, 14))
    assert log._rows.shape[0] == 19  # preallocated for the cap, not for the run
    c = _csv(capped.files["csv"])
    assert len(c["time_s"]) == 250 == capped.rows  # the CSV keeps every cycle
    r = log.record()
    cycles = [*range(0, 250, 14), 249]
    assert np.array_equal(log.row_cycles(), cycles)
    assert np.array_equal(r.t, c["time_s"][cycles]) and np.array_equal(r.com[:, 2], c["com_z_m"][cycles])
    assert np.array_equal(r.fz_mj[:, 1], c["right_foot_fz_mj_N"][cycles])
    assert all("\ncurves: every 14th of 250 cycles (the job's log); figures: every cycle" in title
               for title in log.titles) and len(log.titles) == 2
    assert not any("curves" in title for title in full_log.titles)
    v, vf = capped.values, full.values
    # the plant's figures equal the uncapped run's (the plant is deterministic)
    for key in PLANT_FIGURES:
        assert v[key] == pytest.approx(vf[key], rel=1e-9, abs=0), key
    for foot, median in vf["contact_normal_rel_error_per_foot"].items():
        assert v["contact_normal_rel_error_per_foot"][foot] == pytest.approx(median, rel=1e-9)
    # and the CSV's every cycle: RMS and extremes exactly, the quantiles of the float32 values
    err = np.column_stack([c[f"com_{a}_m"] - c[f"com_ref_{a}_m"] for a in "xyz"])
    assert v["com_error_rms_m"] == pytest.approx(np.sqrt(np.mean(np.sum(err**2, axis=1))), rel=1e-12)
    assert v["max_foot_slip_m"] == np.maximum(c["left_foot_slip_m"], c["right_foot_slip_m"]).max() > 0
    assert v["pelvis_z_min_m"] == c["base_z_m"].min()
    rel = np.abs((c["left_foot_fz_qp_N"] + c["right_foot_fz_qp_N"])
                 - (c["left_foot_fz_mj_N"] + c["right_foot_fz_mj_N"])) / log.mg
    settled = c["time_s"] >= c["time_s"][0] + SETTLE_S  # standing: every settled cycle in stance
    assert v["contact_force_rel_error_max"] == rel[settled].max()  # float64, not rounded
    assert v["contact_force_rel_error_settling_max"] == rel[~settled].max()
    rel32 = rel[settled].astype(np.float32)
    assert v["contact_force_rel_error"] == float(np.median(rel32))
    assert v["contact_force_rel_error_p95"] == float(np.percentile(rel32, 95))
    right = (np.abs(c["right_foot_fz_qp_N"] - c["right_foot_fz_mj_N"]) / log.mg)[settled]
    assert v["contact_normal_rel_error_per_foot"]["right_foot"] == float(np.median(right.astype(np.float32)))
    # the timings: medians of every cycle's, as read from the controller and the simulator
    ctrl_us, qp_us, physics_us = times.T
    assert len(times) == 250
    assert v["controller_time_median_us"] == float(np.median(ctrl_us))
    assert v["qp_solve_time_median_us"] == float(np.median(qp_us[qp_us > 0]))
    assert v["physics_step_time_median_us"] == float(np.median(physics_us))
    assert 0 < v["cycle_overhead_median_us"] < v["cycle_time_median_us"]
    # the mean overhead: every cycle's (each recorded once, BATCH at a time) from the uncapped rows
    rf = full_log.record()
    physics = full_log._rows[: full_log.rows, full_log._extra["physics_us"]]
    overhead = (rf.cycle_us - rf.ctrl_us - physics)[1:]  # the first cycle has no start
    assert vf["cycle_overhead_mean_us"] == pytest.approx(overhead.mean(), rel=1e-5)
    with pytest.raises(ValueError, match="with_truth is for a run over DDS: in-process the CoM is the plant"):
        log.with_truth(np.zeros((250, 3)), fell=False)


def test_the_com_error_behind_latency_is_the_interpolated_ones_over_every_cycle(g1, tmp_path, monkeypatch):
    """10 ms each way: the plant's CoM compared with the reference interpolated at the plant's time."""
    full, full_log, _ = _run(g1, tmp_path / "full", monkeypatch, scenario="squat", duration=0.6,
                             plant=PlantOptions(latency_ms=10.0))
    capped, log, _ = _run(g1, tmp_path / "capped", monkeypatch, cap=20, scenario="squat", duration=0.6,
                          plant=PlantOptions(latency_ms=10.0))
    err = com_tracking_error(full_log.record())  # the whole run's rows, interpolated at once
    assert len(err) < full_log.k  # the last plant samples, after the last reference, are left out
    rms = math.sqrt(np.mean(np.sum(err**2, axis=1)))
    assert full.values["com_error_rms_m"] == pytest.approx(rms, rel=1e-12)
    assert capped.values["com_error_rms_m"] == pytest.approx(rms, rel=1e-9) and rms > 1e-5
    assert log.rows == 20 and log.com_sums.count == len(err)


def test_com_error_sums_equal_the_interpolated_error_with_latency_a_held_start_and_repeated_states():
    rng = np.random.default_rng(3)
    n = 400
    t = np.arange(n) * 0.002
    t[100:103] = t[99]  # the link delivered no new state for three cycles (the state repeats)
    t[103:] -= 0.006
    ref = np.column_stack([np.sin(3 * t), np.cos(2 * t), 0.7 + 0.01 * t])
    t_plant = np.arange(n) * 0.002 + 0.005 + 0.01  # later than the state, by more than a cycle
    t_plant[:5] = t[0] - 0.001 * np.arange(5, 0, -1)  # samples before the first reference: held at it
    com = ref + rng.normal(0, 1e-3, (n, 3))
    sums = CoMErrorSums()
    for k in range(n):
        sums.add(float(t[k]), tuple(ref[k].tolist()), float(t_plant[k]), tuple(com[k].tolist()))
    empty = np.zeros((n, 2))
    r = WBCRecord(t, t_plant, ref, com, *([empty] * 4), np.zeros((n, 2, 2)), np.zeros((n, 2, 2)),
                  *([np.zeros(n)] * 6))
    err = com_tracking_error(r)
    assert sums.count == len(err) < n and not sums.unordered
    assert sums.rms() == pytest.approx(math.sqrt(np.mean(np.sum(err**2, axis=1))), rel=1e-12)
    assert sums.last[1] == pytest.approx(np.linalg.norm(err[-1]), rel=1e-12)


def test_with_truth_compares_every_cycles_truth_with_its_reference_in_a_capped_log(g1, tmp_path, monkeypatch):
    """The log as over DDS (no plant monitor): the truth's CoM against every cycle's kept reference."""
    monkeypatch.setattr(wbc_log, "MAX_LOG_ROWS", 20)
    logs = []
    init = WBCLog.__init__

    def unobserved(self, ctx, wb, monitor, pushes, n, mg_n, q_names, batch):
        init(self, ctx, wb, None, pushes, n, mg_n, q_names, batch)
        logs.append(self)

    monkeypatch.setattr(WBCLog, "__init__", unobserved)
    record = run_job(Job("g1-wbc", partial(prepare, robot=g1)), WBCParams(scenario="squat", duration=0.5),
                     tmp_path)
    log = logs[0]
    c = _csv(record.files["csv"])
    ref = np.column_stack([c[f"com_ref_{a}_m"] for a in "xyz"])
    estimated = np.column_stack([c[f"com_{a}_m"] for a in "xyz"])  # the controller's model CoM
    assert log.rows == 19 and len(ref) == 250 and log._com_ref.shape == (250, 3)
    assert np.isnan(record.values["contact_force_rel_error"]) and log._quantiles.shape == (250, 3)
    rms = np.sqrt(np.mean(np.sum((estimated - ref) ** 2, axis=1)))
    assert record.values["com_error_rms_m"] == pytest.approx(rms, rel=1e-12)
    truth = ref + np.column_stack([np.sin(np.arange(250.0)), np.zeros(250), np.full(250, 1e-3)]) * 1e-3
    values = log.with_truth(truth, fell=False)
    assert values["com_error_source"] == "truth log" and values["fell"] is False
    assert values["com_error_rms_m"] == pytest.approx(np.sqrt(np.mean(np.sum((truth - ref) ** 2, axis=1))),
                                                      rel=1e-12)
    assert np.array_equal(log.record().com, truth[log.row_cycles()])  # the plots' rows
    assert np.allclose(log.com_error_rows()[1], np.linalg.norm(truth - ref, axis=1)[log.row_cycles()])


@pytest.mark.parametrize("latency", [False, True])
def test_com_error_sums_in_blocks_equal_them_cycle_by_cycle(latency):
    rng = np.random.default_rng(4)
    n = 300
    t = np.arange(n) * 0.002
    t_plant = t + (0.005 if latency else 0.0)
    ref = np.column_stack([np.sin(3 * t), np.cos(2 * t), 0.7 + 0.01 * t])
    com = ref + rng.normal(0, 1e-3, (n, 3))
    one, blocks = CoMErrorSums(), CoMErrorSums()
    last = []
    for k in range(n):
        one.add(float(t[k]), tuple(ref[k].tolist()), float(t_plant[k]), tuple(com[k].tolist()))
        last.append(one.last)
    out, at = [], 0
    for b in (1, 64, 0, 7, 128, 100):
        out.append(blocks.add_block(t[at:at + b], ref[at:at + b], t_plant[at:at + b], com[at:at + b]))
        at += b
    assert at == n and blocks.count == one.count == n - (3 if latency else 0)
    assert blocks.sum_sq == pytest.approx(one.sum_sq, rel=1e-13) and blocks.last == one.last
    np.testing.assert_allclose(np.vstack(out), np.array(last), rtol=1e-13, equal_nan=True)


def test_slips_over_batches_equal_the_cycle_by_cycle_rule():
    """A foot's slip counts from where it last did not support (or where it first did)."""
    rng = np.random.default_rng(5)
    n, feet = 500, len(wbc_log.FEET)
    loaded = rng.random((n, feet)) < 0.9
    loaded[:40] = True  # supporting from the start: from where it first did
    xy = np.cumsum(rng.normal(0, 1e-3, (n, feet, 2)), axis=0)
    home: dict[int, tuple[float, float]] = {}
    expected = np.zeros((n, feet))
    for k in range(n):  # the rule, cycle by cycle
        for j in range(feet):
            x, y = xy[k, j]
            if loaded[k, j]:
                hx, hy = home.setdefault(j, (x, y))
                expected[k, j] = math.hypot(x - hx, y - hy)
            else:
                home[j] = (x, y)
    log = WBCLog.__new__(WBCLog)
    log._home = {}
    got, at = [], 0
    for b in (3, 64, 1, 256, 176):
        before = dict(log._home)
        slip, homes = log._slips(loaded[at:at + b], xy[at:at + b])
        assert log._home == before  # nothing changes before the batch's rows are written
        got.append(slip)
        log._home = homes
        at += b
    np.testing.assert_allclose(np.vstack(got), expected, rtol=0, atol=1e-15)
    assert expected[:40].max() > 1e-3 and (expected[~loaded] == 0).all()


def test_ctrl_c_while_a_batch_is_recorded_keeps_every_cycles_row(g1, tmp_path, monkeypatch):
    """Interrupted inside a batch's recording, before its CSV rows: the end of the run records it."""
    sums = wbc_log.sums_block
    calls = []

    def interrupted_once(nets):
        calls.append(len(nets))
        if len(calls) == 1:
            raise KeyboardInterrupt
        return sums(nets)

    monkeypatch.setattr(wbc_log, "sums_block", interrupted_once)
    batch = 256  # a batch within the 1000 cycles
    monkeypatch.setattr(g1_wbc, "BATCH_IN_PROCESS", batch)
    record = run_job(Job("g1-wbc", partial(prepare, robot=g1)), WBCParams(scenario="squat", duration=2.0),
                     tmp_path)
    assert record.status == "interrupted" and calls == [batch, batch]  # the same batch, recorded at the end
    c = _csv(record.files["csv"])
    assert record.rows == len(c["time_s"]) == batch
    np.testing.assert_allclose(np.diff(c["time_s"]), 0.002, rtol=1e-9)  # every cycle once, in order
    assert c["left_foot_fz_mj_N"][-1] > 50.0 and np.isfinite(record.values["contact_force_rel_error"])
