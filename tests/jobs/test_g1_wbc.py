"""``mbctl g1-wbc``: the five scenarios at short durations against the issue's bounds, in MuJoCo."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from functools import partial

import numpy as np
import pytest

from mbctl.jobs.g1_wbc import WBCParams, prepare
from mbctl.jobs.runner import Job, run_job

KEYS = {"fell", "com_error_rms_m", "max_foot_slip_m", "contact_force_rel_error",
        "controller_time_median_us", "qp_solve_time_median_us", "torque_saturation_steps"}


def _run(g1, folder, **kw):
    return run_job(Job("g1-wbc", partial(prepare, robot=g1)), WBCParams(**kw), folder)


def _torques(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    cols = [i for i, name in enumerate(rows[0]) if name.startswith("tau_")]
    return np.array([[float(r[i]) for i in cols] for r in rows[1:]])


def test_squat_tracks_the_com_without_slipping(g1, tmp_path):
    record = _run(g1, tmp_path, scenario="squat", duration=4.0)
    v = record.values
    assert (record.status, record.exit_code) == ("completed", 0)
    assert KEYS <= set(v)
    assert v["fell"] is False
    assert v["com_error_rms_m"] < 5e-3          # measured 2.2 mm over 10 s
    assert v["max_foot_slip_m"] < 1e-3          # measured 0.6 mm
    assert v["contact_force_rel_error"] < 0.05  # measured 2 %
    assert v["torque_saturation_steps"] == 0
    report = json.loads(record.report_path.read_text())
    assert report["bound"] == "CoM RMS < 5 mm, foot slip < 1 mm; did not fall"
    assert {"csv", "plot", "g1_wbc_contacts.png"} <= set(report["outputs"])
    assert record.rows == 2000


def test_one_foot_releases_lifts_and_puts_back_the_foot_with_bounded_torque_steps(g1, tmp_path):
    record = _run(g1, tmp_path, scenario="one-foot")
    v = record.values
    assert (record.status, v["fell"]) == ("completed", False)
    assert v["max_foot_slip_m"] < 1e-3
    with open(record.files["csv"], newline="") as f:
        rows = list(csv.DictReader(f))
    t = np.array([float(r["time_s"]) for r in rows])
    fz_right = np.array([float(r["right_foot_fz_mj_N"]) for r in rows])
    lifted = (t > 4.0) & (t < 8.0)
    assert np.all(fz_right[lifted] == 0.0)  # the right foot is off the floor while held up
    assert fz_right[-1] > 0.3 * 9.81 * 33.3  # and carries load again at the end
    # force ramps: no torque jump at the release (t = 2-2.3 s) or the touch-down (9.5 s)
    steps = np.abs(np.diff(_torques(record.files["csv"]), axis=0)).max(axis=1)
    assert steps.max() < 5.0  # N m per 2 ms cycle


@pytest.mark.parametrize("scenario,duration", [("stand", 2.0), ("reach", 4.0), ("push", 3.5)])
def test_other_scenarios_balance(g1, tmp_path, scenario, duration):
    record = _run(g1, tmp_path, scenario=scenario, duration=duration)
    v = record.values
    assert (record.status, record.exit_code, v["fell"]) == ("completed", 0, False)
    assert v["contact_force_rel_error"] < 0.05
    assert v["com_error_rms_m"] < 0.01


def test_bad_input_exits_2_with_the_reason(tmp_path):
    for args, message in ((["jump"], "unknown scenario 'jump'; choose one of stand, squat"),
                          (["push", "--impulse", "-1"], "impulse must be a finite impulse >= 0 N s")):
        out = subprocess.run([sys.executable, "-m", "mbctl.cli", "g1-wbc", *args, "--output",
                              str(tmp_path)], capture_output=True, text=True, timeout=60)
        assert out.returncode == 2, out.stderr
        assert message in out.stderr and "Traceback" not in out.stderr
