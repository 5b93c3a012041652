"""g1-walk's log of a long run: its plots' rows capped, every reported figure still over every cycle.

The cap (``MAX_LOG_ROWS``, 100,000 rows) is patched down to 20 rows so a 2 s walk (1000 cycles)
is a long one. The medians and 95th percentiles are of float32 inputs (7 significant digits).
"""

from __future__ import annotations

from functools import partial

import numpy as np
import pytest

from mbctl.jobs import g1_walk_log
from mbctl.jobs.g1_walk import WalkParams, prepare
from mbctl.jobs.g1_walk_log import WalkLog
from mbctl.jobs.runner import Job, run_job
from tests.jobs.log_spy import spy_on_log

#: Figures that do not depend on the wall clock: the same in two runs of the deterministic plant.
PLANT_FIGURES = ("fell", "steps", "max_foot_slip_m", "median_foot_slip_m", "min_zmp_margin_m",
                 "min_cmp_margin_m", "cmp_clamped_fraction", "dcm_rms_m", "dcm_max_error_m", "walk_time_s",
                 "distance_m")


def _run(g1, folder, monkeypatch, cap=None):
    """A 2 s forward walk: the record, its log, every cycle's controller and QP times [us] from the source."""
    if cap is not None:
        monkeypatch.setattr(g1_walk_log, "MAX_LOG_ROWS", cap)

    def times(log: WalkLog) -> tuple[float, float]:
        return log.walker.compute_time_s * 1e6, log.walker.wbc.solution.qp_time_s * 1e6

    return spy_on_log(monkeypatch, WalkLog, lambda: run_job(Job("g1-walk", partial(prepare, robot=g1)),
                      WalkParams("forward", speed="0.3", duration=2.0), folder), times)


def test_a_capped_walk_log_keeps_20_rows_and_reports_every_cycles_figures(g1, tmp_path, monkeypatch):
    full, full_log, _ = _run(g1, tmp_path / "full", monkeypatch)
    capped, log, times = _run(g1, tmp_path / "capped", monkeypatch, cap=20)
    assert capped.status == full.status == "completed"
    # the plots' rows: every 53rd cycle and the last (20 rows); the uncapped log every cycle
    assert (full_log.stride, full_log.rows) == (1, 1000)
    assert (log.stride, log.rows, log._rows.shape[0]) == (53, 20, 20)
    path = capped.files["csv"]
    names = path.read_text().splitlines()[0].split(",")
    rows = np.loadtxt(path, delimiter=",", skiprows=1)
    c = {name: rows[:, i] for i, name in enumerate(names)}
    assert len(rows) == 1000 == capped.rows  # the CSV keeps every cycle
    kept = log.record().columns
    cycles = [*range(0, 1000, 53), 999]
    assert np.array_equal(kept["time_s"], c["time_s"][cycles])
    assert np.array_equal(kept["dcm_x_m"], c["dcm_x_m"][cycles])
    note = "\ncurves: every 53th of 1,000 cycles (the job's log); figures: every cycle"
    assert len(log.titles) == 2 and all(note in t for t in log.titles)
    assert not any("curves" in t for t in full_log.titles)
    v, vf = capped.values, full.values
    assert v["steps"] >= 2 and v["fell"] is False
    for key in PLANT_FIGURES:  # the uncapped run's
        assert v[key] == pytest.approx(vf[key], rel=1e-9, abs=0), key
    for phase, stats in vf["contact_force_error"].items():
        for key, value in stats.items():
            assert v["contact_force_error"][phase][key] == pytest.approx(value, rel=1e-9), (phase, key)
    # and the CSV's every cycle: the DCM's RMS, largest, the margins, the force error's quantiles
    dcm = np.hypot(c["dcm_x_m"] - c["dcm_ref_x_m"], c["dcm_y_m"] - c["dcm_ref_y_m"])
    assert v["dcm_rms_m"] == pytest.approx(np.sqrt(np.mean(dcm**2)), rel=1e-12)
    assert v["dcm_max_error_m"] == dcm.max()
    walking = c["phase"] > 0
    assert v["min_zmp_margin_m"] == c["zmp_ref_margin_m"][walking].min()
    assert v["min_cmp_margin_m"] == c["cmp_margin_m"].min()
    assert v["walk_time_s"] == c["time_s"][-1] - c["time_s"][0]
    err = np.abs(sum(c[f"{f}_fz_qp_N"] - c[f"{f}_fz_mj_N"] for f in ("left_foot", "right_foot")))
    for phase, code in (("single", 1), ("double", 2)):
        e = err[c["phase"] == code]
        stats = v["contact_force_error"][phase]
        assert stats["max_N"] == e.max()  # float64, not rounded
        assert stats["median_N"] == float(np.median(e.astype(np.float32)))
        assert stats["p95_N"] == float(np.percentile(e.astype(np.float32), 95))
    # the timings: medians of every cycle's, as read from the controller
    assert len(times) == 1000
    assert v["controller_time_median_us"] == float(np.median(times[:, 0]))
    assert v["qp_solve_time_median_us"] == float(np.median(times[times[:, 1] > 0, 1]))
