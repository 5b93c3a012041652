"""The 2-link square demo job: tracking on the plant, outputs through the runner."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from mbctl.control.exceptions import ControllerSetupError
from mbctl.jobs.demo import DEMO, SITE, DemoConfig, square_reference, track_square
from mbctl.jobs.runner import run_job
from mbctl.robots.edits import scale_masses
from mbctl.sim.recorder import read_csv


@pytest.fixture(scope="module")
def square(two_link_torque_gravity):
    return square_reference(two_link_torque_gravity, DemoConfig(), two_link_torque_gravity.timestep_s)


def test_ct_square_is_sub_millimetre_with_gravity(two_link_torque_gravity, square):
    result, _ = track_square(two_link_torque_gravity, square, DemoConfig(controller="ct"))
    assert result.rms_error_m < 1e-3
    assert result.max_error_m < 1e-3
    assert result.saturated_cycles == 0


def test_pd_gravity_beats_pd_and_ct_beats_both(two_link_torque_gravity, square):
    rms = {
        name: track_square(two_link_torque_gravity, square, DemoConfig(controller=name))[0].rms_error_m
        for name in ("pd", "pd_gravity", "ct", "task_ct")
    }
    assert rms["pd_gravity"] < 0.5 * rms["pd"]
    assert rms["ct"] < 0.2 * rms["pd_gravity"]
    assert rms["task_ct"] < 1e-3


def test_model_error_degrades_computed_torque(two_link_torque_gravity, square):
    exact, _ = track_square(two_link_torque_gravity, square, DemoConfig())
    wrong, _ = track_square(two_link_torque_gravity, square, DemoConfig(model_error_pct=30.0))
    assert wrong.rms_error_m > 3.0 * exact.rms_error_m
    assert wrong.model_error_pct == 30.0
    scaled = scale_masses(two_link_torque_gravity.pin_model, 1.3)
    assert scaled.inertias[1].mass == pytest.approx(1.3 * two_link_torque_gravity.pin_model.inertias[1].mass)
    assert two_link_torque_gravity.pin_model.inertias[1].mass == pytest.approx(1.0)  # original untouched


def test_demo_writes_outputs(tmp_path):
    record = run_job(DEMO, DemoConfig(duration_s=0.3, model_error_pct=10.0), tmp_path)
    assert record.status == "completed" and record.exit_code == 0
    for role in ("csv", "plot", "report"):
        assert record.files[role].is_file()
    report = json.loads(record.files["report"].read_text())
    assert report["job"] == "demo" and report["status"] == "completed"
    # 0.3 s at 500 Hz: 150 cycles, every one a row; the RMS is that of those rows
    assert report["rows"] == 150
    table = read_csv(record.files["csv"])
    assert table["time_s"].size == 150
    rms = float(np.sqrt(np.mean(table["error_m"] ** 2)))
    assert report["values"]["rms_error_m"] == pytest.approx(rms, rel=1e-12)
    assert 1e-6 < rms < 5e-3  # 10 % mass error: small but not exact
    assert report["exact_model"]["model_error_pct"] == 0.0
    assert report["exact_model"]["rms_error_m"] < report["values"]["rms_error_m"]
    assert {"time_s", "p_ref_x_m", "p_x_m", "error_m", "tau_shoulder_N_m"} <= set(table)
    with pytest.raises(ControllerSetupError, match="choose one of"):
        DemoConfig(controller="lqr")


def test_demo_cli(tmp_path):
    out = subprocess.run(
        [sys.executable, "-m", "mbctl.cli", "demo", "--duration", "0.2", "--compare",
         "--output", str(tmp_path)],
        capture_output=True, text=True, check=True,
    ).stdout
    assert "Cartesian RMS error" in out and "PD + gravity" in out and "computed torque" in out
    assert (tmp_path / "demo.png").is_file()


def test_demo_bound_exits_1(tmp_path):
    out = subprocess.run(
        [sys.executable, "-m", "mbctl.cli", "demo", "--duration", "0.2", "--controller", "pd",
         "--max-rms-mm", "0.001", "--output", str(tmp_path), "--quiet"],
        capture_output=True, text=True,
    )
    assert out.returncode == 1, out.stderr
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["status"] == "completed" and report["passed"] is False


def test_pd_improves_with_model_error_because_its_gains_grow(two_link_torque_gravity, square, tmp_path):
    """The measured explanation of "PD gets better as the model error grows": PD uses the model
    for its gains only, so +40 % masses is the exact model at omega sqrt(I_model / I_plant)."""
    robot = two_link_torque_gravity
    record = run_job(DEMO, DemoConfig(controller="pd", model_error_pct=40.0), tmp_path)
    values = record.values
    ratio = np.array(list(values["pd_gain_ratio"].values()))
    omega = np.array(list(values["pd_effective_omega_rad_s"].values()))
    assert np.all((1.3 < ratio) & (ratio < 1.4))  # masses +40 %, the armature unchanged
    np.testing.assert_allclose(omega, 30.0 * np.sqrt(ratio))
    exact = json.loads(record.report_path.read_text())["exact_model"]["rms_error_m"]
    assert values["rms_error_m"] < 0.8 * exact  # better with the "wrong" model ...
    stiffer, _ = track_square(robot, square, DemoConfig(controller="pd", omega_rad_s=float(omega.mean())))
    assert stiffer.rms_error_m == pytest.approx(values["rms_error_m"], rel=0.02)  # ... as a stiffer PD is
    assert any(line.startswith("why: joint PD uses the model only for its gains") and "35." in line
               for line in record.outcome.summary)


@pytest.mark.parametrize("name", ["ct", "task_ct"])
def test_a_capped_loop_log_keeps_the_demo_figures_of_every_cycle(two_link_torque_gravity, square, monkeypatch,
                                                                  name):
    """The loop's log capped at 50 rows: the errors are still every cycle's, the curves the rows'."""
    from mbctl.control import loop
    from mbctl.jobs.recording import PlantSite

    config = DemoConfig(controller=name, duration_s=1.0)  # 500 cycles
    full, _ = track_square(two_link_torque_gravity, square, config)
    assert full.log.stride == 1
    p = PlantSite(two_link_torque_gravity, SITE).many(full.log.q)[:, :2]
    err = np.linalg.norm(full.p_ref - p, axis=1)  # every cycle, from the full-rate log
    assert full.rms_error_m == pytest.approx(np.sqrt(np.mean(err**2)), rel=1e-12)
    assert full.max_error_m == err.max()
    monkeypatch.setattr(loop, "MAX_LOG_ROWS", 50)
    capped, _ = track_square(two_link_torque_gravity, square, config)
    assert capped.log.stride == 11 and len(capped.t_s) == len(capped.p) == 47
    for key in ("rms_error_m", "max_error_m", "joint_rms_error_rad"):
        assert getattr(capped, key) == pytest.approx(getattr(full, key), rel=1e-12, abs=0), key
    np.testing.assert_array_equal(capped.p_ref, full.p_ref[capped.log.cycle])
