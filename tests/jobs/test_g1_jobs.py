"""The G1 jobs on the runner: standing, welded-base tracking, arm PD; interruption and locking."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from functools import partial

import numpy as np
import pytest

from mbctl.jobs.g1 import (
    ArmPDParams,
    StandParams,
    TrackParams,
    prepare_arm_pd,
    prepare_stand,
    prepare_track,
)
from mbctl.jobs.runner import LOCK_NAME, Job, run_job
from mbctl.sim.recorder import read_csv


def _run(prepare, params, g1, folder):
    return run_job(Job("g1-test", partial(prepare, robot=g1)), params, folder)


def test_g1_stands_under_pd_gravity(g1, tmp_path):
    record = _run(prepare_stand, StandParams(duration_s=3.0), g1, tmp_path)
    v = record.values
    assert (record.status, record.exit_code) == ("completed", 0)
    assert v["simulated_time_s"] == pytest.approx(3.0)
    assert v["pelvis_max_deviation_m"] < 0.005  # 1.6 mm over 10 s; the bound is 20 mm
    assert v["fell"] is False and v["saturated_cycles"] == 0
    report = json.loads(record.report_path.read_text())
    assert report["run"]["warnings"] == {}  # no divergence warning of any kind
    assert report["rows"] == 1500 == record.rows
    table = read_csv(record.files["csv"])
    # the CSV holds the full q (pelvis pose included) and the command, one row per cycle
    assert {"floating_base_joint_z_m", "floating_base_joint_qw", "q_left_knee_joint_rad",
            "tau_left_knee_joint_N_m", "q_ref_left_knee_joint_rad"} <= set(table)
    z = table["floating_base_joint_z_m"]
    deviation = np.max(np.abs(z - v["pelvis_z_keyframe_m"]))
    assert deviation == pytest.approx(v["pelvis_max_deviation_m"], abs=2e-4)
    assert record.files["plot"].stat().st_size > 20_000


def test_g1_welded_computed_torque_tracks_ruckig(g1, tmp_path):
    record = _run(prepare_track, TrackParams(), g1, tmp_path)
    v = record.values
    assert v["joint_rms_error_rad"] < 1e-3
    assert v["saturated_cycles"] == 0 and v["contacts_at_end"] == 0
    table = read_csv(record.files["csv"])
    for joint in ("left_knee_joint", "right_knee_joint", "left_elbow_joint", "right_shoulder_pitch_joint"):
        assert np.ptp(table[f"q_ref_{joint}_rad"]) > 0.15  # arms and legs really move
    # a bound the run misses: completed, outside its bound, exit 1
    missed = _run(prepare_track, TrackParams(duration_s=0.5, max_rms_error_rad=1e-9), g1, tmp_path)
    assert (missed.status, missed.exit_code) == ("completed", 1)


def test_g1_arm_pd_through_position_targets(g1, tmp_path):
    v = _run(prepare_arm_pd, ArmPDParams(), g1, tmp_path).values
    assert v["joint_rms_error_rad"] < 5e-3
    assert v["final_max_error_rad"] < 1e-3
    assert v["pelvis_max_deviation_m"] < 0.02


def test_g1_params_are_checked():
    from mbctl.exceptions import ToolkitError

    with pytest.raises(ToolkitError, match="duration_s must be finite and > 0; got -1"):
        StandParams(duration_s=-1.0)
    with pytest.raises(ToolkitError, match="side must be 'left' or 'right'; got 'up'"):
        ArmPDParams(side="up")


def _start_stand(folder, env):
    return subprocess.Popen(
        [sys.executable, "-m", "mbctl.cli", "g1-stand", "--duration", "3600", "--output", str(folder)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
    )


def _wait_for_rows(folder, n=200, timeout_s=60.0):
    path = folder / "g1_stand.csv"
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout_s:
        if path.exists() and path.read_text().count("\n") > n:
            return
        time.sleep(0.1)
    raise AssertionError("the run wrote no rows")


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_interrupted_run_keeps_every_row_and_exits_130(g1, tmp_path, sig):
    env = {**os.environ, "MENAGERIE_ROOT": str(g1.source.robot_file.parent.parent)}
    proc = _start_stand(tmp_path, env)
    _wait_for_rows(tmp_path)
    proc.send_signal(sig)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("interrupted at t=")
    n_rows = int(lines[0].split("wrote ")[1].split(" rows")[0])
    with open(tmp_path / "g1_stand.csv", newline="") as f:
        rows = list(csv.reader(f))
    header, body = rows[0], rows[1:]
    assert len(body) == n_rows > 200
    assert all(len(r) == len(header) for r in body)  # no torn row
    times = np.array([float(r[0]) for r in body])
    assert np.all(np.diff(times) > 0)
    assert f"t={times[-1]:.3f} s" in lines[0]
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["status"] == "interrupted" and report["rows"] == n_rows
    assert sorted(os.listdir(tmp_path)) == ["g1_stand.csv", "report.json"]  # no temp or lock file


def test_second_run_into_a_busy_folder_refuses(g1, tmp_path):
    env = {**os.environ, "MENAGERIE_ROOT": str(g1.source.robot_file.parent.parent)}
    first = _start_stand(tmp_path, env)
    try:
        _wait_for_rows(tmp_path, n=10)
        second = subprocess.run(
            [sys.executable, "-m", "mbctl.cli", "g1-stand", "--duration", "1", "--output", str(tmp_path)],
            capture_output=True, text=True, env=env, timeout=120,
        )
        assert second.returncode == 2
        assert f"another mbctl run (pid {first.pid}) is writing to" in second.stderr
        assert (tmp_path / LOCK_NAME).read_text() == str(first.pid)
    finally:
        first.send_signal(signal.SIGINT)
        first.communicate(timeout=60)
    assert json.loads((tmp_path / "report.json").read_text())["status"] == "interrupted"
