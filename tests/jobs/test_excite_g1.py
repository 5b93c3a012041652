"""The G1's excitation survives the model error it exists to find, and its balance watch stops it in time.

The guard: the README's payload excitation (2 kg hidden on the torso), shortened to 16 s, the
shortest run that still takes both steps; before the swing-leg fix it fell (the 30 s run at
t = 25.6 s) or its QP had no solution (the 16 s run at t = 7.9 s). Then the balance watch, made
touchy: it scales the motion down, stops it into a stance, and the G1 stands to the end.
"""

from __future__ import annotations

import csv
import json

import numpy as np
import pinocchio as pin
import pytest

from mbctl.jobs import excite_g1_balance, options
from mbctl.jobs.excite import EXCITE
from mbctl.jobs.excite_g1_steps import STEP_TIMES_S
from mbctl.jobs.runner import run_job
from mbctl.robots.g1 import FEET, FOOT_BODIES

PAYLOAD = "2.0@torso_link:0.05,0,0.25"


def _read(run):
    with (run / "excite.csv").open() as f:
        reader = csv.reader(f)
        names = next(reader)
        rows = np.array([[float(x) for x in row] for row in reader])
    return {n: rows[:, i] for i, n in enumerate(names)}, json.loads((run / "report.json").read_text())


def test_the_payload_excitation_stands_its_steps_and_puts_each_foot_back(g1_torque, tmp_path):
    out = tmp_path / "excite"
    record = run_job(EXCITE, options.excite("g1", duration=16.0, payload=PAYLOAD), out)
    assert record.exit_code == 0, record.message
    log, report = _read(out)
    v = report["values"]
    assert v["fell"] is False and v["balance_stopped_at_s"] is None and v["balance_scaled_at_s"] is None
    assert v["min_balance_margin_m"] > excite_g1_balance.SCALE_MARGIN_M  # measured: 9.6 mm
    assert v["samples_with_other_contacts"] == 0
    assert v["swing_leg_ik"]["not_converged"] == 0 and v["swing_leg_ik"]["solves"] > 2000
    assert len(report["identification_log"]["excitation"]["steps"]) == 2
    assert "commanded" not in report["identification_log"]["torques"]  # in-process: applied, measured
    # each foot left the floor for its lift (the plant's contact flag) and came back where it stood
    model = g1_torque.pin_model
    data = model.createData()
    q_cols = report["identification_log"]["q_columns"]
    poses = []
    for k in (0, -1):
        pin.framesForwardKinematics(model, data, np.array([log[c][k] for c in q_cols]))
        poses.append({f: pin.SE3(data.oMf[model.getFrameId(f)]) for f in FEET})
    for foot, body in zip(FEET, FOOT_BODIES, strict=True):
        off = (1.0 - log[f"contact_{body}"]).sum() * 0.002
        assert STEP_TIMES_S[2] + STEP_TIMES_S[3] < off < sum(STEP_TIMES_S[1:5])  # lifted, held, lowered
        moved = poses[0][foot].actInv(poses[1][foot])
        assert np.linalg.norm(moved.translation) < 0.005  # measured: 1-3 mm
        assert np.linalg.norm(pin.log3(moved.rotation)) < 0.01


def test_a_touchy_watch_scales_then_stops_and_the_g1_stands_to_the_end(tmp_path, monkeypatch, g1):
    # margins of this motion are 40-80 mm: a watch that scales under 60 mm and stops under 45 mm acts
    monkeypatch.setattr(excite_g1_balance, "SCALE_MARGIN_M", 0.06)
    monkeypatch.setattr(excite_g1_balance, "STOP_MARGIN_M", 0.045)
    out = tmp_path / "stopped"
    record = run_job(EXCITE, options.excite("g1", duration=7.0, period=4.0, harmonics=2), out)
    assert record.exit_code == 1  # stopped: the excitation did not run its course (the log is kept)
    log, report = _read(out)
    v = report["values"]
    assert v["fell"] is False and v["rows"] == 3500 == len(log["time_s"])
    scaled, stopped = v["balance_scaled_at_s"], v["balance_stopped_at_s"]
    assert scaled is not None and stopped is not None and scaled < stopped < 7.0 - 2.0
    assert v["balance_scalings"][0]["scale"] == pytest.approx(excite_g1_balance.SCALE_FACTOR)
    assert "from the edge of the support" in v["balance_stop_reason"]
    assert report["passed"] is False
    assert report["bound"] == "did not fall and was not stopped by the balance watch"
    # once the motion ramped out, the robot stands still: the pelvis stays put, the joints hardly move
    still = log["time_s"] > stopped + excite_g1_balance.SCALE_RAMP_S + 0.5
    base = np.column_stack([log[f"floating_base_joint_{a}_m"][still] for a in "xyz"])
    assert np.ptp(base, axis=0).max() < 0.002  # measured: below 0.1 mm
    speeds = np.column_stack([log[c][still] for c in log if c.startswith("v_")])
    assert np.percentile(np.abs(speeds), 95) < 0.05  # (a wrist creeps through its dry friction)
