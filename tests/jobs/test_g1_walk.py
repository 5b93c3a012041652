"""``mbctl g1-walk``: a short G1 walk in MuJoCo, its figures read back from the streamed CSV."""

from __future__ import annotations

import json
import math
from functools import partial

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from mbctl.control.exceptions import WBCSetupError
from mbctl.jobs.g1_walk import WalkParams, g1_walk_params, parse_speed, prepare
from mbctl.jobs.g1_walk_choices import WALK_DEFAULT_DURATION_S
from mbctl.jobs.g1_walk_displacement import commanded_path, displacement_values, turn_along
from mbctl.jobs.g1_walk_push import pushes_duration_s
from mbctl.jobs.runner import Job, run_job
from mbctl.planners import VelocityCommand

KEYS = {"fell", "distance_m", "mean_speed_m_s", "steps", "max_foot_slip_m", "median_foot_slip_m",
        "min_zmp_margin_m", "dcm_rms_m", "contact_force_error", "displacement_fraction", "yaw_fraction",
        "touchdowns", "step_adaptations", "controller_time_median_us"}


def _run(g1, folder, **kw):
    return run_job(Job("g1-walk", partial(prepare, robot=g1)), WalkParams(**kw), folder)


def _csv(record):
    path = record.files["csv"]
    names = path.read_text().splitlines()[0].split(",")
    rows = np.loadtxt(path, delimiter=",", skiprows=1)
    return {name: rows[:, i] for i, name in enumerate(names)}


def test_the_g1_walks_forward_and_the_csv_says_so(g1, tmp_path):
    record = _run(g1, tmp_path, scenario="forward", speed="0.3", duration=4.0)
    v = record.values
    assert record.status == "completed" and KEYS <= set(v)
    assert v["fell"] is False and v["controller_fallback_at_s"] is None
    c = _csv(record)
    assert record.rows == len(c["time_s"]) == 2000
    # from the CSV: the pelvis went forward (0.3 m/s from the first step at 0.8 s, reached at 0.5 m/s^2)
    dx, dy = c["pelvis_x_m"][-1] - c["pelvis_x_m"][0], c["pelvis_y_m"][-1] - c["pelvis_y_m"][0]
    assert 0.7 < dx < 1.0  # measured 0.89 m
    # straight: the feet's middle (the pelvis sways 5 cm each way from foot to foot) stays on y = 0
    mid_y = 0.5 * (c["left_foot_y_m"] + c["right_foot_y_m"])
    assert abs(mid_y[-1] - mid_y[0]) < 0.03
    assert c["pelvis_z_m"].min() > 0.65  # it never sagged toward the fall height (0.5 m)
    assert v["distance_m"] == pytest.approx(math.hypot(dx, dy), abs=0.01)  # the report's, from the plant
    # at least 4 steps, alternating feet (the CSV's stance column: 1 left, 2 right in single support)
    stances = c["stance"][c["phase"] == 1]
    changes = stances[np.flatnonzero(np.diff(stances)) + 1]
    assert v["steps"] >= 5 and np.all(np.abs(np.diff(changes)) == 1)
    # the DCM follows its plan: RMS from the CSV's columns equals the report's, within 2 cm
    err = np.hypot(c["dcm_x_m"] - c["dcm_ref_x_m"], c["dcm_y_m"] - c["dcm_ref_y_m"])
    assert np.sqrt(np.mean(err**2)) == pytest.approx(v["dcm_rms_m"], rel=1e-9) and v["dcm_rms_m"] < 0.02
    # the ZMP reference stays inside the support polygon (in single support the sole's centre: 27 mm in)
    assert 0.005 < v["min_zmp_margin_m"] <= 0.028
    # one foot carries the weight in single support, in MuJoCo: the swing foot's force is zero
    single = c["phase"] == 1
    swing_fz = np.where(c["stance"] == 1, c["right_foot_fz_mj_N"], c["left_foot_fz_mj_N"])[single]
    assert np.median(swing_fz) == 0.0
    mg = g1.mj_model.body_subtreemass[1] * 9.81
    force = v["contact_force_error"]["single"]
    assert force["median_N"] < 0.05 * mg and force["p95_N"] <= force["max_N"]
    # the stance soles hold (the moment feedforward and the QP's friction margins, docs/api/walking.rst):
    # each stance's drift within 5 mm, from the CSV's slip columns (measured 4.3 mm; ~15 mm without them)
    slip = np.maximum(c["left_foot_slip_m"], c["right_foot_slip_m"])
    assert slip.max() == pytest.approx(v["max_foot_slip_m"], abs=1e-9) and v["max_foot_slip_m"] < 0.005
    report = json.loads(record.report_path.read_text())
    assert {"csv", "plot", "g1_walk_forces.png"} <= set(report["outputs"])
    assert report["inputs"]["command_applied"] == [0.3, 0.0, 0.0]


def test_commanded_path_integrates_the_command_with_its_turn():
    t = np.linspace(0.0, 2.0, 2001)
    d, yaw = commanded_path(t, VelocityCommand(0.5, 0.0, 0.0), 0.0)
    np.testing.assert_allclose(d, [1.0, 0.0], atol=1e-9)
    d, yaw = commanded_path(t, VelocityCommand(0.5, 0.0, math.pi / 2), 0.0)  # a quarter circle of radius 1/pi
    assert yaw == pytest.approx(math.pi)
    np.testing.assert_allclose(d, [0.0, 2 / math.pi], atol=2e-3)


def _path(yaw: np.ndarray) -> np.ndarray:
    """Base configurations (rows, 7) at the origin, turned by ``yaw`` [rad] (quaternion x, y, z, w)."""
    q = np.zeros((len(yaw), 7))
    q[:, 5], q[:, 6] = np.sin(yaw / 2), np.cos(yaw / 2)
    return q


@given(st.floats(-30.0, 30.0), st.floats(-math.pi, math.pi))
def test_the_turn_along_a_path_counts_whole_turns(turn, yaw0):
    yaw = yaw0 + turn * np.linspace(0.0, 1.0, 400) ** 2  # under pi between rows
    assert turn_along(_path(yaw)) == pytest.approx(turn, abs=1e-9)


def test_a_course_reports_its_turn_from_the_path_and_no_command_figures():
    # a course (the default one turns once around) run 60 s with its speed caps' 0.3 rad/s as the command:
    # unwrapped against that command's 18 rad, the pelvis's 6.3 rad turn was reported as 18.9
    t = np.linspace(0.0, 60.0, 3001)
    q = _path(np.linspace(0.0, 2 * math.pi + 0.3, len(t)))
    q[-1, :2] = [1.5, 0.3]
    course = displacement_values(q[0], q[-1], t, None, q)
    assert course["yaw_rad"] == pytest.approx(2 * math.pi + 0.3, abs=1e-9)
    assert course["distance_m"] == pytest.approx(math.hypot(1.5, 0.3))
    for key in ("commanded_displacement_m", "displacement_fraction", "commanded_yaw_rad", "yaw_fraction"):
        assert course[key] is None, key
    turning = displacement_values(q[0], q[-1], t, VelocityCommand(0.0, 0.0, 0.3), q)
    assert turning["commanded_yaw_rad"] == pytest.approx(18.0)
    assert turning["yaw_fraction"] == pytest.approx((2 * math.pi + 0.3) / 18.0)


def test_speed_parsing_and_bad_input():
    assert parse_speed("0.3") == (0.3, 0.0, 0.0) and parse_speed("0,0.2") == (0.0, 0.2, 0.0)
    assert WalkParams("backward", speed="0.3").command == VelocityCommand(-0.3, 0.0, 0.0)
    assert WalkParams("turn").command == VelocityCommand(0.0, 0.0, 0.5)
    for bad in ("", "a", "1,2,3,4", "nan"):
        with pytest.raises(WBCSetupError, match="--speed must be"):
            parse_speed(bad)
    with pytest.raises(WBCSetupError, match="unknown scenario 'jog'"):
        WalkParams("jog")
    params = g1_walk_params("side", "0,0.1", 2.0, latency_ms=2.0, payload="1.0@torso_link")
    assert params.plant.latency_ms == 2.0 and params.models.payload == "1.0@torso_link"


def test_the_quick_gait_walks_the_g1_at_1_m_s_where_the_normal_one_is_capped(g1, tmp_path):
    """The quick gait (the default): 0.28 s steps, 1.0 m/s not clamped; the normal gait caps it at its
    forward step limit and says where more is to be had (a 20 s quick walk: 20.6 m, docs/api/walking.rst)."""
    record = _run(g1, tmp_path / "quick", scenario="forward", speed="1.0", duration=3.0)
    v, c = record.values, _csv(record)
    report = json.loads(record.report_path.read_text())
    assert report["inputs"]["gait"] == "quick" and report["inputs"]["command_applied"] == [1.0, 0.0, 0.0]
    assert report["inputs"]["timing_s"] == {"single_support_s": 0.28, "double_support_s": 0.03}
    assert v["fell"] is False and v["steps"] >= 7
    dx = c["pelvis_x_m"][-1] - c["pelvis_x_m"][0]
    assert 1.8 < dx < 2.6  # measured 2.2 m: 0.6 s on both feet, then the ramp to 1.0 m/s at 1 m/s^2
    normal = _run(g1, tmp_path / "normal", scenario="forward", speed="1.0", duration=0.2, gait="normal")
    assert normal.values["steps"] == 0
    assert ("command 1,0,0 limited to 0.624,0,0 by the forward step limit; the quick gait (the default) "
            "steps quicker, up to ~1 m/s") in normal.outcome.summary
    with pytest.raises(WBCSetupError, match="unknown gait 'fast'; choose one of quick, normal"):
        WalkParams(gait="fast")


@pytest.mark.parametrize("phase, starts_s", [("early", 3.05 + 0.1 * 0.28), ("late", 3.05 + 0.6 * 0.28),
                                             ("double", 3.0)])
def test_a_push_waits_for_its_gait_phase_not_any_cycle_past_it(g1, phase, starts_s):
    """Due at 3.0 s late in a swing (at 89 % of it): an early or late push waits for the next swing
    to pass 10 or 60 % (the quick gait's 0.28 s swings met every due time past 60 %: early and late
    were the same push); a double-support push starts at the due time when it is in double support."""
    from types import SimpleNamespace

    from mbctl.jobs.g1_walk_push import PhasePushes

    class Path:
        def __init__(self, t0_s):
            self.t0_s = t0_s

        def at(self, t_s):
            return SimpleNamespace(phase=(t_s - self.t0_s) / 0.28)

    first, second = SimpleNamespace(path=Path(2.75)), SimpleNamespace(path=Path(3.05))
    status = SimpleNamespace(phase="single", dcm=np.zeros(2), dcm_ref=np.zeros(2))
    gait = SimpleNamespace(t0_s=0.0, swing=first, steps=0)
    walker = SimpleNamespace(status=status, gait=gait)
    pushes = PhasePushes(g1.mj_model, walker, [90.0], 15.0, phase)
    for k in range(int(round(2.9 / 0.002)), int(round(3.4 / 0.002))):
        t = k * 0.002
        double = 2.75 + 0.28 <= t < 3.05 or (phase == "double" and t >= 2.99)  # (a double support at 3.0)
        status.phase = "double" if double else "single"
        gait.swing = None if double else first if t < 3.05 else second
        pushes.on_cycle(t, t, False)
    assert len(pushes.records) == 1
    assert pushes.records[0].time_s == pytest.approx(starts_s, abs=0.002 + 1e-9)


def test_a_push_held_0_08_s_applies_impulse_over_hold_and_reports_it(g1, tmp_path):
    # the eight directions planned, the run long enough for the first (0 deg) only: said, exit 1
    record = _run(g1, tmp_path, scenario="push", speed="0.3", impulse=8.0, push_hold=0.08, duration=3.6)
    assert record.exit_code == 1 and record.values["pushes_applied"] == 1
    assert ("; 7 not applied: the run ended at 3.60 s before they were due (8 pushes need --duration 28 or "
            "more)") in record.outcome.summary[-1]
    assert pushes_duration_s(8) == WALK_DEFAULT_DURATION_S["push"]
    (push,) = record.values["pushes"]
    assert (push["impulse_n_s"], push["hold_s"]) == (8.0, 0.08)
    assert push["force_n"] == pytest.approx(100.0) and push["survived"] is True
    # read back from the CSV (one row a 2 ms control cycle): 100 N along +x for 0.08 s, 8 N s
    c = _csv(record)
    dt = float(np.median(np.diff(c["time_s"])))
    fx, fy = c["push_fx_N"], c["push_fy_N"]
    assert fx.max() == pytest.approx(100.0) and np.abs(fy).max() < 1e-9
    assert 0.08 - 1e-9 <= np.count_nonzero(fx) * dt <= 0.08 + dt + 1e-9
    assert fx.sum() * dt == pytest.approx(8.0, abs=100.0 * dt + 1e-9)
    report = json.loads(record.report_path.read_text())
    assert report["values"]["pushes"][0]["force_n"] == pytest.approx(100.0)


def test_push_hold_is_checked_and_named():
    assert WalkParams("push", push_hold=0.08).push_hold == 0.08
    assert g1_walk_params("push", push_hold=0.05).push_hold == 0.05
    for bad in (0.0, -0.1, math.nan, math.inf):
        with pytest.raises(WBCSetupError, match=rf"push_hold must be a finite time > 0 s; got {bad}$"):
            WalkParams("push", push_hold=bad)
    with pytest.raises(WBCSetupError, match="--push-hold applies to the push scenario only"):
        WalkParams("forward", push_hold=0.1)


def test_a_sweep_passes_push_hold_by_name_and_rejects_a_bad_one_before_any_task(tmp_path):
    from mbctl.jobs.catalog import CATALOG, SweepInputError, parse_grid
    from mbctl.jobs.sweep import SweepConfig, prepare_sweep

    grid = parse_grid("g1-walk", ["scenario=push", "impulse=48", "push_hold=0.08,0.1"])
    assert grid["push_hold"] == [0.08, 0.1]
    params = CATALOG["g1-walk"].params({"scenario": "push", "impulse": 48.0, "push_hold": 0.08})
    assert (params.impulse, params.push_hold) == (48.0, 0.08)
    grid = parse_grid("g1-walk", ["scenario=push", "push_hold=0.08,-0.1"])
    bad = SweepConfig("g1-walk", grid, tmp_path / "s")
    with pytest.raises(SweepInputError, match=r"push_hold must be a finite time > 0 s; got -0.1"):
        prepare_sweep(bad)
    assert not (tmp_path / "s").exists()
