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

from mbctl.jobs.exceptions import OutputError
from mbctl.jobs.g1 import (
    ArmPDParams,
    StandParams,
    TrackParams,
    prepare_arm_pd,
    prepare_stand,
    prepare_track,
)
from mbctl.jobs.g1_plots import limb_rows
from mbctl.jobs.plant import PlantOptionError, PlantOptions
from mbctl.jobs.plots import coincident_groups
from mbctl.jobs.recording import q_columns, v_columns
from mbctl.jobs.runner import LOCK_NAME, Job, run_job
from mbctl.robots.g1 import limb_of
from mbctl.sim.recorder import read_csv


def _run(prepare, params, g1, folder, name="g1-test"):
    return run_job(Job(name, partial(prepare, robot=g1)), params, folder)


def _header(path):
    with open(path, newline="") as f:
        return next(csv.reader(f))


def test_g1_stands_under_pd_gravity(g1, tmp_path):
    record = _run(prepare_stand, StandParams(duration_s=3.0), g1, tmp_path, "g1-stand")
    v = record.values
    assert (record.status, record.exit_code) == ("completed", 0)
    assert v["simulated_time_s"] == pytest.approx(3.0)
    # measured 1.61 mm (the contact settles in the first 0.2 s, then holds); bound 20 mm
    assert 1e-4 < v["pelvis_max_deviation_m"] < 2.0e-3
    assert v["joint_rms_error_rad"] < 5e-3
    assert v["fell"] is False and v["saturated_cycles"] == 0
    assert (v["commanded_cycles"], v["commanded_fraction"], v["controller_acted"]) == (1500, 1.0, True)
    report = json.loads(record.report_path.read_text())
    assert (report["status"], report["passed"]) == ("completed", True)
    assert report["bound"] == "did not fall; pelvis within 20 mm of the keyframe height"
    assert report["run"]["warnings"] == {}  # no divergence warning of any kind
    assert report["rows"] == 1500 == record.rows
    # one row per cycle: time, reference, the full q (pelvis pose included), v, torques, base height
    header = _header(record.files["csv"])
    assert header[0] == "time_s" and header[-1] == "base_z_m"
    assert header[30:30 + g1.nq] == q_columns(g1)
    assert header[30 + g1.nq:30 + g1.nq + g1.nv] == v_columns(g1)
    assert len(header) == 1 + 29 + g1.nq + g1.nv + 29 + 1
    assert {"q_ref_left_knee_joint_rad", "tau_left_knee_joint_N_m", "floating_base_joint_qw"} <= set(header)
    table = read_csv(record.files["csv"])
    np.testing.assert_array_equal(table["base_z_m"], table["floating_base_joint_z_m"])
    deviation = np.max(np.abs(table["base_z_m"] - v["pelvis_z_keyframe_m"]))
    assert deviation == pytest.approx(v["pelvis_max_deviation_m"], abs=2e-4)
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "g1_stand.csv", "g1_stand.png", "model.xml", "report.json", "trajectory.npz"]
    assert record.files["plot"].stat().st_size > 20_000


def test_g1_that_falls_exits_1(g1, tmp_path):
    # gains for 1 rad/s cannot hold the body: in 1.5 s it sinks well past the 20 mm bound (exit 1)
    # without having fallen yet; by 3 s the torso is on the floor (the G1's fall rule)
    record = _run(prepare_stand, StandParams(duration_s=1.5, omega_rad_s=1.0), g1, tmp_path / "sink")
    assert (record.status, record.exit_code) == ("completed", 1)
    assert record.values["fell"] is False and record.values["pelvis_max_deviation_m"] > 0.05
    record = _run(prepare_stand, StandParams(duration_s=3.0, omega_rad_s=1.0), g1, tmp_path / "fall")
    assert (record.status, record.exit_code) == ("completed", 1)
    assert record.values["fell"] is True and record.values["fall_reason"] == "torso_link touched the floor"
    report = json.loads(record.report_path.read_text())
    assert report["passed"] is False and "FELL (torso_link touched the floor)" in record.summary()


def test_a_run_whose_controller_never_acted_is_not_a_pass(g1, tmp_path):
    """Every command lost: the plant was held still, the robot "stood" 0.00 mm; exit 1, status uncommanded."""
    record = _run(prepare_stand, StandParams(duration_s=0.3, plant=PlantOptions(drop=0.999)), g1,
                  tmp_path / "drop", "g1-stand")
    v = record.values
    assert (record.status, record.exit_code) == ("uncommanded", 1)
    assert (v["commanded_cycles"], v["commanded_fraction"], v["controller_acted"]) == (0, 0.0, False)
    assert v["pelvis_max_deviation_m"] == 0.0 and v["held_s"] == pytest.approx(0.3)  # held still throughout
    assert record.message == (
        "the controller never acted: no command reached the plant in any of the run's 150 control cycles (at "
        "least 50% are needed); the plant was held still 0.300 s waiting for its first command; 150 commands "
        "lost (--drop 0.999): the run's figures are the plant's alone")
    report = json.loads(record.report_path.read_text())
    assert (report["status"], report["passed"], report["message"]) == ("uncommanded", False, record.message)
    assert report["rows"] == 150  # the rows are kept
    assert record.summary().startswith("NOT A PASS (uncommanded): the controller never acted")
    assert "stood" not in record.summary()


def test_a_run_commanded_in_under_half_its_cycles_is_not_a_pass(g1, tmp_path):
    """A latency of 3/4 of the run: commands reach the arm in its last quarter only."""
    record = _run(prepare_arm_pd, ArmPDParams(duration_s=0.2, plant=PlantOptions(latency_ms=150.0)), g1,
                  tmp_path, "g1-arm-pd")
    v = record.values
    assert (record.status, record.exit_code) == ("uncommanded", 1)
    assert (v["commanded_cycles"], v["cycles"], v["controller_acted"]) == (25, 100, False)
    assert record.message.startswith("the controller acted in too few cycles to judge it: a command reached "
                                     "the plant in 25 of the run's 100 control cycles")
    assert "held still 0.150 s waiting for its first command (--latency-ms 150)" in record.message


def test_a_latency_as_long_as_the_run_is_refused_up_front(g1, tmp_path):
    with pytest.raises(PlantOptionError, match=r"--latency-ms 1e\+09 is not shorter than the run \(10 s\): "
                                                r"no command would reach the plant"):
        StandParams(plant=PlantOptions(latency_ms=1e9))
    with pytest.raises(PlantOptionError, match=r"--latency-ms 10000 is not shorter than the run \(2\.\d+ "):
        prepare_arm_pd(ArmPDParams(plant=PlantOptions(latency_ms=1e4)), robot=g1)  # the whole trajectory's
    assert not any(tmp_path.iterdir())


def test_g1_welded_computed_torque_tracks_ruckig(g1, tmp_path):
    record = _run(prepare_track, TrackParams(), g1, tmp_path)
    v = record.values
    assert (record.status, record.exit_code) == ("completed", 0)
    # measured 1.135e-4 rad over the whole 2.6 s trajectory
    assert 5e-5 < v["joint_rms_error_rad"] < 1.5e-4
    assert v["joint_max_error_rad"] < 1e-3
    assert v["saturated_cycles"] == 0 and v["contacts_at_end"] == 0
    header = _header(record.files["csv"])
    welded = len(header) - 1 - 29 - 29  # time, reference, q, v (29 each: welded base), torques
    assert welded == 29 + 29 and "base_z_m" not in header
    table = read_csv(record.files["csv"])
    assert len(table["time_s"]) == record.rows == json.loads(record.report_path.read_text())["rows"]
    for joint in ("left_knee_joint", "right_knee_joint", "left_elbow_joint", "right_shoulder_pitch_joint"):
        assert np.ptp(table[f"q_ref_{joint}_rad"]) > 0.15  # arms and legs really move
    # a bound the run misses: completed, outside its bound, exit 1
    missed = _run(prepare_track, TrackParams(duration_s=0.5, max_rms_error_rad=1e-9), g1, tmp_path)
    assert (missed.status, missed.exit_code) == ("completed", 1)
    assert json.loads(missed.report_path.read_text())["bound"] == "joint RMS error <= 1e-09 rad"


def test_g1_arm_pd_through_position_targets(g1, tmp_path):
    record = _run(prepare_arm_pd, ArmPDParams(max_rms_error_rad=2e-3), g1, tmp_path)
    v = record.values
    assert (record.status, record.exit_code) == ("completed", 0)
    assert v["joint_rms_error_rad"] < 1.5e-3  # measured 7.9e-4 rad
    assert v["final_max_error_rad"] < 1e-3
    assert v["pelvis_max_deviation_m"] < 5e-3 and v["fell"] is False
    assert v["other_joints_max_deviation_rad"] < 0.05  # the body held still while the arm moved
    report = json.loads(record.report_path.read_text())
    assert report["bound"] == ("joint RMS error <= 0.002 rad; did not fall; pelvis within 20 mm of the "
                               "keyframe height")
    header = _header(record.files["csv"])
    assert header[1] == "q_ref_left_shoulder_pitch_joint_rad" and header[-1] == "base_z_m"
    assert "target_left_elbow_joint_rad" in header
    assert len(header) == 1 + 7 + g1.nq + g1.nv + 7 + 1


#: The figures each job reports over every cycle (not the wall time, the plant's timing).
EXACT = {
    "g1-stand": ("pelvis_z_min_m", "pelvis_z_max_m", "pelvis_z_final_m", "pelvis_max_deviation_m",
                 "joint_rms_error_rad", "joint_max_error_rad", "fell", "saturated_cycles", "cycles"),
    "g1-track": ("joint_rms_error_rad", "joint_max_error_rad", "final_max_error_rad", "worst_joint",
                 "worst_joint_rms_error_rad", "rms_error_by_joint_rad", "saturated_cycles"),
    "g1-arm-pd": ("joint_rms_error_rad", "joint_max_error_rad", "final_max_error_rad", "worst_joint",
                  "rms_error_by_joint_rad", "other_joints_max_deviation_rad", "pelvis_max_deviation_m",
                  "fell", "cycles"),
}


@pytest.mark.parametrize("name, prepare, params", [
    ("g1-stand", prepare_stand, StandParams(duration_s=0.4)),
    ("g1-track", prepare_track, TrackParams(duration_s=0.4)),
    ("g1-arm-pd", prepare_arm_pd, ArmPDParams(duration_s=0.4)),
])
def test_a_capped_loop_log_reports_the_figures_of_every_cycle(g1, tmp_path, monkeypatch, name, prepare,
                                                               params):
    """The loop's log capped at 20 rows (every 11th of 200 cycles): every figure as with every row."""
    from mbctl.control import loop

    full = _run(prepare, params, g1, tmp_path / "full", name)
    monkeypatch.setattr(loop, "MAX_LOG_ROWS", 20)
    capped = _run(prepare, params, g1, tmp_path / "capped", name)
    assert capped.exit_code == full.exit_code and capped.rows == full.rows == 200  # the CSV: every cycle
    for key in EXACT[name]:
        a, b = capped.values[key], full.values[key]
        if isinstance(a, dict):
            assert a.keys() == b.keys()
            np.testing.assert_allclose(list(a.values()), list(b.values()), rtol=1e-12, atol=0)
        elif isinstance(a, float):
            assert a == pytest.approx(b, rel=1e-12, abs=0), key
        else:
            assert a == b, key
    assert capped.values["joint_rms_error_rad"] > 0 and capped.files["plot"].exists()
    # the figures are those of the CSV's rows, every cycle (the capped log kept 20 of them)
    table = read_csv(capped.files["csv"])
    q_ref = np.column_stack([table[c] for c in table if c.startswith("q_ref_")])
    joints = [c[len("q_ref_"):-len("_rad")] for c in table if c.startswith("q_ref_")]
    q = np.column_stack([table[f"q_{j}_rad"] for j in joints])
    assert capped.values["joint_rms_error_rad"] == pytest.approx(np.sqrt(np.mean((q_ref - q) ** 2)), rel=1e-9)


def test_g1_params_are_checked():
    from mbctl.exceptions import ToolkitError

    with pytest.raises(ToolkitError, match="duration_s must be finite and > 0; got -1"):
        StandParams(duration_s=-1.0)
    with pytest.raises(ToolkitError, match="max_rms_error_rad must be finite and > 0; got 0"):
        TrackParams(max_rms_error_rad=0.0)
    with pytest.raises(ToolkitError, match="side must be 'left' or 'right'; got 'up'"):
        ArmPDParams(side="up")
    # an hour on the robot is ordinary (the CSV streams, the replay is bounded); the cap is an hour
    assert StandParams(duration_s=3600.0).duration_s == 3600.0
    assert ArmPDParams(duration_s=3600.0).duration_s == 3600.0
    with pytest.raises(ToolkitError, match="--duration 3,601 s exceeds mbctl's limit of 3,600 s; a run over "
                                           "an hour is a CSV of over 1.8 million rows"):
        StandParams(duration_s=3601.0)


def test_plot_grouping_helpers(g1):
    joints = tuple(j for j in g1.joints if j != "floating_base_joint")
    assert {limb_of(j) for j in joints} == {"left leg", "right leg", "waist", "left arm", "right arm"}
    reference = np.zeros((10, len(joints)))
    reference[:, joints.index("right_elbow_joint")] = np.linspace(0, 1, 10)
    rows = limb_rows(joints, reference)
    assert [limb for limb, _ in rows] == ["right arm"] and len(rows[0][1]) == 7  # still limbs left out
    t = np.linspace(0, 1, 50)
    a = np.c_[np.sin(t), np.sin(t) + 1e-4, -np.sin(t), np.cos(t)]
    assert coincident_groups((a,), [0, 1, 2, 3]) == [[0, 1], [2], [3]]
    b = a.copy()
    b[:, 1] += 1.0  # same in one signal, different in the other: drawn separately
    assert coincident_groups((a, b), [0, 1, 2, 3]) == [[0], [1], [2], [3]]


def _env(g1):
    return {**os.environ, "MENAGERIE_ROOT": str(g1.source.robot_file.parent.parent)}


def _start_stand(folder, env, duration="600"):
    # mbctl's longest run (limits.py): still running when the test signals it, however fast the machine
    return subprocess.Popen(
        [sys.executable, "-m", "mbctl.cli", "g1-stand", "--duration", duration, "--output", str(folder)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
    )


def _wait_for_rows(proc, folder, n):
    """Block until the running job has streamed more than ``n`` rows (a condition, not a delay).

    Bounded by how long the job may take to start on a loaded machine (the G1 loads in ~1 s
    alone); a job that exits or stalls first fails the test with its stderr.
    """
    path, deadline = folder / "g1_stand.csv", time.monotonic() + 300.0
    while not (path.exists() and path.read_text().count("\n") > n):
        if proc.poll() is not None:
            raise AssertionError(f"the job exited ({proc.returncode}) first: {proc.stderr.read()}")
        if time.monotonic() > deadline:
            raise AssertionError(f"no {n} rows in {path} within 300 s")
        time.sleep(0.02)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_interrupted_run_keeps_every_row_and_exits_130(g1, tmp_path, sig):
    proc = _start_stand(tmp_path, _env(g1))
    _wait_for_rows(proc, tmp_path, n=100)  # signalled mid-run, after 100 control cycles
    proc.send_signal(sig)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("interrupted at t="), err
    n_rows = int(lines[0].split("wrote ")[1].split(" rows")[0])
    assert lines[0].endswith(f"rows to {tmp_path / 'g1_stand.csv'}")
    with open(tmp_path / "g1_stand.csv", newline="") as f:
        rows = list(csv.reader(f))
    header, body = rows[0], rows[1:]
    assert len(body) == n_rows > 10
    assert all(len(r) == len(header) for r in body)  # no torn row
    times = np.array([float(r[0]) for r in body])
    assert np.all(np.diff(times) > 0) and times[-1] < 600.0
    assert f"t={times[-1]:.3f} s" in lines[0]
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["status"] == "interrupted" and report["rows"] == n_rows
    assert report["last_time_s"] == pytest.approx(times[-1])
    assert not list(tmp_path.glob(".*.tmp")) and not (tmp_path / LOCK_NAME).exists()
    assert sorted(os.listdir(tmp_path)) == ["g1_stand.csv", "model.xml", "report.json", "trajectory.npz"]

    # another job's run into the folder is refused, the interrupted run kept (issue 31)
    with pytest.raises(OutputError, match="holds a run of `mbctl g1-stand`"):
        _run(prepare_track, TrackParams(duration_s=0.1), g1, tmp_path, "g1-track")
    assert sorted(os.listdir(tmp_path)) == ["g1_stand.csv", "model.xml", "report.json", "trajectory.npz"]
    # the next run of the same job replaces it, leaving no file of the interrupted one beside its own
    record = _run(prepare_stand, StandParams(duration_s=0.1), g1, tmp_path, "g1-stand")
    assert record.status == "completed" and record.rows < n_rows
    assert sorted(os.listdir(tmp_path)) == [
        "g1_stand.csv", "g1_stand.png", "model.xml", "report.json", "trajectory.npz"]


def test_run_after_a_diverged_run_leaves_none_of_its_files(g1, tmp_path):
    from mbctl.robots import load_robot

    unstable = load_robot("g1", model_dir=g1.source.robot_file.parent)
    unstable.mj_model.opt.timestep = 0.05  # 25x the G1's 2 ms: the position actuators blow up
    diverged = _run(prepare_arm_pd, ArmPDParams(duration_s=1.0), unstable, tmp_path, "g1-arm-pd")
    assert (diverged.status, diverged.exit_code) == ("diverged", 1)
    assert "BADQACC" in (diverged.message or "")
    assert sorted(os.listdir(tmp_path)) == ["g1_arm_pd.csv", "model.xml", "report.json", "trajectory.npz"]
    assert json.loads((tmp_path / "report.json").read_text())["rows"] == diverged.rows > 0

    with pytest.raises(OutputError, match="holds a run of `mbctl g1-arm-pd`"):
        _run(prepare_stand, StandParams(duration_s=0.1), g1, tmp_path, "g1-stand")
    record = _run(prepare_arm_pd, ArmPDParams(duration_s=0.1), g1, tmp_path, "g1-arm-pd")
    assert record.status == "completed"
    assert sorted(os.listdir(tmp_path)) == [
        "g1_arm_pd.csv", "g1_arm_pd.png", "model.xml", "report.json", "trajectory.npz"]


def test_second_run_into_a_busy_folder_refuses(g1, tmp_path):
    env = _env(g1)
    first = _start_stand(tmp_path, env)
    try:
        _wait_for_rows(first, tmp_path, n=10)
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


def test_model_dir_is_honoured(g1, tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "MENAGERIE_ROOT"}
    model_dir = g1.source.robot_file.parent
    ok = subprocess.run(
        [sys.executable, "-m", "mbctl.cli", "g1-track", "--duration", "0.05", "--model-dir", str(model_dir),
         "--output", str(tmp_path / "ok"), "--quiet"],
        capture_output=True, text=True, env=env, timeout=120,
    )
    assert ok.returncode == 0, ok.stderr
    report = json.loads((tmp_path / "ok" / "report.json").read_text())
    assert str(model_dir) in report["model"]["origin"]
    missing = tmp_path / "no_such_g1"
    bad = subprocess.run(
        [sys.executable, "-m", "mbctl.cli", "g1-arm-pd", "--model-dir", str(missing),
         "--output", str(tmp_path / "bad"), "--quiet"],
        capture_output=True, text=True, env=env, timeout=120,
    )
    assert bad.returncode == 2
    assert bad.stderr.startswith(f"error: Model directory '{missing}' does not exist")
    assert not any((tmp_path / "bad").iterdir())  # bad input: nothing written
