"""excite and identify as a user runs them: the 2-link hidden truth, write-back, bad logs (exit 2)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import mbctl.robots
from mbctl.cli import _register_commands, app
from mbctl.control.exceptions import ControllerSetupError
from mbctl.jobs import options
from mbctl.jobs.demo import DEMO
from mbctl.jobs.excite import EXCITE
from mbctl.jobs.identify import IDENTIFY, load_nominal
from mbctl.jobs.identify import prepare as prepare_identify
from mbctl.jobs.runner import run_job
from mbctl.planners.exceptions import InvalidPlanningInput
from mbctl.robots.identification import BadLogError, ParameterSet, model_fingerprint
from mbctl.robots.identification.inertial import consistency_problems, from_inertial
from mbctl.robots.identification.pipeline import base_parameter_errors
from mbctl.robots.registry import load_robot

_register_commands()


@pytest.fixture(scope="module")
def two_link_run(tmp_path_factory):
    """A short excitation of the 2-link arm whose plant's links are 20 % heavier than modelled."""
    out = tmp_path_factory.mktemp("excite") / "run"
    params = options.excite("two_link_torque", duration=6.0, period=3.0, harmonics=3, plant_error=20.0)
    record = run_job(EXCITE, params, out)
    assert record.exit_code == 0, record.message
    return out


@pytest.fixture(scope="module")
def identified(two_link_run, tmp_path_factory):
    out = tmp_path_factory.mktemp("identify") / "run"
    record = run_job(IDENTIFY, options.identify([str(two_link_run)]), out)
    assert record.exit_code == 0, record.message
    return out


def test_two_link_hidden_truth_base_parameters_within_one_percent(two_link_run, identified):
    report = json.loads((identified / "identify_report.json").read_text())
    truth_set = ParameterSet(load_robot(two_link_run / "model.xml"))  # the plant as it ran: the truth
    truth = dict(zip(truth_set.names, truth_set.nominal, strict=True))
    base = report["identifiability"]["base_parameters"]
    assert len(base) == report["identifiability"]["structural_rank"] == 6
    coefficients = [b["coefficients"] for b in base]
    assert base_parameter_errors(coefficients, [b["identified"] for b in base], truth).max() < 0.01
    assert base_parameter_errors(coefficients, [b["nominal"] for b in base], truth).max() > 0.15  # hidden
    v = report["validation"]
    assert v["torque_rmse_identified"] < 0.01 * v["torque_rmse_nominal"]
    for name, body in report["bodies"].items():  # every estimate is a physical body
        pi = from_inertial(body["mass_kg"]["identified"], np.array(body["com_m"]["identified"]),
                           np.array(body["inertia_kg_m2"]["identified"]))
        assert consistency_problems(pi) == [], name


def test_unidentifiable_parameters_are_reported_with_the_reason(identified):
    report = json.loads((identified / "identify_report.json").read_text())
    why = {x["parameter"]: x["reason"] for x in report["identifiability"]["not_identified"]}
    assert why["link1.m"].startswith("no joint torque of this robot depends on it in any motion")
    assert "in every motion (structural" in why["link2.m"]
    assert len(why) == 30 - 1  # only link1.mcy is identifiable on its own


def test_identified_model_loads_and_both_engines_agree(identified):
    model = identified / "identified.xml"
    robot = load_robot(model)
    assert robot.nv == 2
    report = json.loads((identified / "identify_report.json").read_text())
    assert report["identified_model"]["round_trip_max_rel_error"] < 1e-4
    out = CliRunner().invoke(app, ["xcheck", str(model), "--states", "30", "--output", str(identified / "x")])
    assert out.exit_code == 0, out.output
    assert "result: PASS" in out.output


def test_demo_with_the_identified_controller_model(identified, tmp_path):
    def rms(**extra):
        record = run_job(DEMO, options.demo(plant_error=20.0, **extra), tmp_path / str(len(extra)))
        return record.values["rms_error_m"]

    nominal, with_identified = rms(), rms(controller_model=str(identified / "identified.xml"))
    assert nominal > 1e-3 and with_identified <= 0.15e-3, (nominal, with_identified)


def _copy(run, tmp_path, name):
    target = tmp_path / name
    shutil.copytree(run, target)
    return target


def _edit_csv(folder, edit):
    path = folder / "excite.csv"
    lines = path.read_text().splitlines()
    path.write_text("\n".join(edit(lines)) + "\n")


def _bad_logs(two_link_run, tmp_path):
    short = _copy(two_link_run, tmp_path, "short")
    _edit_csv(short, lambda lines: lines[:300])
    nan = _copy(two_link_run, tmp_path, "nan")
    _edit_csv(nan, lambda lines: lines[:500] + [",".join(["nan", *lines[500].split(",")[1:]])] + lines[501:])
    still = _copy(two_link_run, tmp_path, "still")
    _edit_csv(still, lambda lines: [lines[0]] + [f"{k * 0.002!r}," + ",".join(lines[1].split(",")[1:])
                                                  for k in range(len(lines) - 1)])
    missing = _copy(two_link_run, tmp_path, "missing")
    header = (two_link_run / "excite.csv").read_text().splitlines()[0].split(",")
    drop = header.index("tau_elbow_N_m")
    _edit_csv(missing, lambda lines: [",".join(x for i, x in enumerate(ln.split(",")) if i != drop)
                                      for ln in lines])
    return {"short": short, "nan": nan, "still": still, "missing": missing}


SIX_DOF = """<mujoco><worldbody><body name="a"><joint name="j1"/><inertial pos="0 0 0.1" mass="1"
diaginertia="0.01 0.01 0.01"/></body></worldbody><actuator><motor joint="j1"/></actuator></mujoco>"""


@pytest.mark.parametrize("case, message", [
    ("short", "too short: 299 rows over 0.596 s"),
    ("nan", "1 non-finite values in time_s, the first at data row 499, time_s column 0"),
    ("still", "does not excite the robot: its equations have rank"),
    ("missing", "lacks the columns ['tau_elbow_N_m']"),
    ("other robot", "is a log of 'two_link_torque'"),
    ("demo run", "was recorded by `mbctl demo`, not `mbctl excite`"),
    ("no folder", "is not a folder"),
])
def test_bad_logs_are_refused_with_the_reason(two_link_run, tmp_path, case, message):
    runs = _bad_logs(two_link_run, tmp_path) if case in ("short", "nan", "still", "missing") else {}
    robot = None
    if case == "other robot":
        (tmp_path / "other.xml").write_text(SIX_DOF)
        runs[case], robot = two_link_run, str(tmp_path / "other.xml")
    elif case == "demo run":
        runs[case] = tmp_path / "demo"
        run_job(DEMO, options.demo(duration=0.1), runs[case])
    elif case == "no folder":
        runs[case] = tmp_path / "nowhere"
    with pytest.raises(BadLogError, match=message.replace("[", r"\[").replace("(", r"\(")):
        prepare_identify(options.identify([str(runs[case])], robot=robot))


def test_a_bad_log_exits_2_with_the_reason_and_writes_nothing(two_link_run, tmp_path):
    run = _bad_logs(two_link_run, tmp_path)["nan"]
    out = subprocess.run([sys.executable, "-m", "mbctl.cli", "identify", str(run), "--output",
                          str(tmp_path / "id")], capture_output=True, text=True, timeout=120, env=os.environ)
    assert out.returncode == 2, out.stderr
    assert "non-finite values in time_s" in out.stderr and "Traceback" not in out.stderr
    assert not (tmp_path / "id" / "identify_report.json").exists()


def test_excite_refuses_robots_it_cannot_excite(tmp_path):
    path = tmp_path / "free.xml"
    path.write_text('<mujoco><worldbody><body name="b"><freejoint/><inertial pos="0 0 0" mass="1" '
                    'diaginertia="1 1 1"/><body name="c"><joint name="j"/><inertial pos="0 0 0" mass="1" '
                    'diaginertia="1 1 1"/></body></body></worldbody><actuator><motor joint="j"/></actuator>'
                    "</mujoco>")
    from mbctl.jobs.excite import prepare

    with pytest.raises(ControllerSetupError, match="has a floating base; excite runs fixed-base robots"):
        prepare(options.excite(str(path)))


# --- issue 31: bad inputs of identify and excite -------------------------------------------------

ASSETS = Path(mbctl.robots.__file__).parent / "assets"


@pytest.fixture(scope="module")
def heavy_arm(tmp_path_factory):
    """Another 2-link arm: the same joint names as two_link_torque, link2 3 kg instead of 0.7 kg."""
    folder = tmp_path_factory.mktemp("heavy_arm")
    arm = (ASSETS / "two_link_arm.xml").read_text()
    assert arm.count('mass="0.7"') == 1
    (folder / "two_link_arm.xml").write_text(arm.replace('mass="0.7"', 'mass="3.0"'))
    (folder / "heavy_arm.xml").write_text((ASSETS / "two_link_torque.xml").read_text())
    return folder / "heavy_arm.xml"


@pytest.fixture(scope="module")
def heavy_arm_run(heavy_arm, tmp_path_factory):
    """An exact excitation of the heavy arm (no hidden truth)."""
    out = tmp_path_factory.mktemp("excite_heavy") / "run"
    record = run_job(EXCITE, options.excite(str(heavy_arm), duration=6.0, period=3.0, harmonics=3), out)
    assert record.exit_code == 0, record.message
    return out


def _fingerprint(run):
    return json.loads((run / "report.json").read_text())["identification_log"]["model_fingerprint"]


def _escape(text):
    return "".join("\\" + c if c in "[]().*+?{}|^$\\" else c for c in text)


def test_a_log_of_another_arm_with_the_same_joints_is_refused_naming_both_models(two_link_run, heavy_arm_run):
    mine, theirs = _fingerprint(two_link_run)[:12], _fingerprint(heavy_arm_run)[:12]
    assert mine != theirs
    params = options.identify([str(heavy_arm_run)], robot="two_link_torque")
    section = json.loads((heavy_arm_run / "report.json").read_text())["identification_log"]
    nominal = model_fingerprint(load_nominal(params, section))[:12]  # two_link_torque, the log's gravity
    with pytest.raises(BadLogError, match=_escape(
            f"the log's model is not the model being identified, 'two_link_torque' (fingerprint {nominal}): "
            f"{heavy_arm_run} was recorded on {theirs}; another arm with the same joint names gives wrong "
            "parameters")):
        prepare_identify(params)
    # two logs of two arms together: the second is not the first's model
    with pytest.raises(BadLogError, match=_escape(
            f"(fingerprint {mine}, as in {two_link_run}): {heavy_arm_run} was recorded on {theirs};")):
        prepare_identify(options.identify([str(two_link_run), str(heavy_arm_run)]))


def test_a_log_without_a_fingerprint_is_refused_unless_allowed(two_link_run, tmp_path):
    run = _copy(two_link_run, tmp_path, "no_fingerprint")
    report = json.loads((run / "report.json").read_text())
    del report["identification_log"]["model_fingerprint"]
    (run / "report.json").write_text(json.dumps(report))
    with pytest.raises(BadLogError, match=_escape(
            f"{run} records no model fingerprint (not an mbctl excite log of this version); ")):
        prepare_identify(options.identify([str(run)]))
    prepare_identify(replace(options.identify([str(run)]), allow_other_model=True))  # no raise


def test_another_arms_log_exits_2_and_the_override_is_recorded(heavy_arm_run, tmp_path):
    def cli(*extra):
        return subprocess.run([sys.executable, "-m", "mbctl.cli", "identify", str(heavy_arm_run), "--robot",
                               "two_link_torque", "--output", str(tmp_path / "id"), "-q", *extra],
                              capture_output=True, text=True, timeout=300, env=os.environ)

    refused = cli()
    assert refused.returncode == 2, refused.stderr
    assert "the log's model is not the model being identified" in refused.stderr
    assert "--allow-other-model" in refused.stderr and "Traceback" not in refused.stderr
    assert not (tmp_path / "id" / "identify_report.json").exists()
    allowed = cli("--allow-other-model")
    assert allowed.returncode in (0, 1), allowed.stderr
    assert f"--allow-other-model: {heavy_arm_run} recorded on another model" in allowed.stdout
    report = json.loads((tmp_path / "id" / "identify_report.json").read_text())
    assert report["allow_other_model"] is True
    assert report["logs"][0]["same_nominal_model"] is False
    assert report["logs"][0]["recorded_with_fingerprint"] == _fingerprint(heavy_arm_run)


def test_non_increasing_time_is_named_with_the_row_and_values(two_link_run, tmp_path):
    reversed_run = _copy(two_link_run, tmp_path, "reversed")
    _edit_csv(reversed_run, lambda lines: [lines[0], *lines[1:][::-1]])
    lines = (reversed_run / "excite.csv").read_text().splitlines()
    t0, t1 = float(lines[1].split(",")[0]), float(lines[2].split(",")[0])
    with pytest.raises(BadLogError, match=_escape(
            f"excite.csv has non-increasing time: data row 1 has time_s {t1!r} s after {t0!r} s at row 0 "
            f"({len(lines) - 2} such rows)")):
        prepare_identify(options.identify([str(reversed_run)]))
    swapped = _copy(two_link_run, tmp_path, "swapped")
    _edit_csv(swapped, lambda lines: [*lines[:101], lines[102], lines[101], *lines[103:]])
    lines = (swapped / "excite.csv").read_text().splitlines()
    t100, t101 = float(lines[101].split(",")[0]), float(lines[102].split(",")[0])
    with pytest.raises(BadLogError, match=_escape(
            f"data row 101 has time_s {t101!r} s after {t100!r} s at row 100 (1 such rows)")):
        prepare_identify(options.identify([str(swapped)]))


def test_sign_flipped_torques_are_refused_not_identified(two_link_run, tmp_path):
    flipped = _copy(two_link_run, tmp_path, "flipped")
    header = (two_link_run / "excite.csv").read_text().splitlines()[0].split(",")
    tau = {i for i, name in enumerate(header) if name.startswith("tau_")}

    def flip(lines):
        return [lines[0]] + [",".join(repr(-float(x)) if i in tau else x for i, x in enumerate(ln.split(",")))
                             for ln in lines[1:]]

    _edit_csv(flipped, flip)
    with pytest.raises(BadLogError, match=_escape(
            "the logged torques run against the nominal model's: cosine similarity of measured and predicted "
            "torque shoulder (-1.00), elbow (-1.00) (< -0.5;")):
        prepare_identify(options.identify([str(flipped)]))


def test_an_exact_log_of_the_exact_model_is_not_worse_within_the_noise_floor(tmp_path):
    run = tmp_path / "exact"
    assert run_job(EXCITE, options.excite("two_link_torque", duration=6.0, period=3.0, harmonics=3, seed=1),
                   run).exit_code == 0
    record = run_job(IDENTIFY, options.identify([str(run)]), tmp_path / "id")
    nominal, identified = record.values["torque_rmse_nominal"], record.values["torque_rmse_identified"]
    assert nominal < 1e-5  # both at the noise floor of an exact log
    assert nominal < identified < 1.01 * nominal  # worse by a hair: within the tolerance
    assert record.exit_code == 0, record.message
    report = json.loads((tmp_path / "id" / "identify_report.json").read_text())
    assert report["validation"]["worse_when"].startswith("identified > (1 + 0.01) x nominal")


def test_a_killed_excitation_is_called_incomplete(two_link_run, tmp_path):
    killed = _copy(two_link_run, tmp_path, "killed")
    report = json.loads((killed / "report.json").read_text())
    report.update(status="running", message=None, pid=4242)  # the report a run writes when it starts
    del report["identification_log"]
    (killed / "report.json").write_text(json.dumps(report))
    with pytest.raises(BadLogError, match=_escape(
            f"{killed} holds an incomplete `mbctl excite` run: its report.json still says status 'running' "
            "(pid 4242): the run is still going, or was killed (SIGKILL, power loss) before it wrote its "
            "report, so its report has no 'identification_log' section and excite.csv cannot be read; wait "
            "for a running excitation to finish, or record it again with mbctl excite")):
        prepare_identify(options.identify([str(killed)]))


def test_excite_refuses_too_many_harmonics_and_too_short_a_period(tmp_path):
    with pytest.raises(ControllerSetupError, match=_escape(
            "--harmonics must be 1 to 10; got 500 (more harmonics only slow the design")):
        options.excite("two_link_torque", harmonics=500)
    with pytest.raises(ControllerSetupError, match=_escape(
            "--period 1e-06 s with 5 harmonics puts the highest harmonic at 5e+06 Hz; the joints follow up "
            "to 4.77 Hz (the tracking's 30 rad/s): give --period >= 1.05 s or fewer harmonics")):
        options.excite("two_link_torque", period=1e-6)
    out = subprocess.run([sys.executable, "-m", "mbctl.cli", "excite", "two_link_torque", "--harmonics",
                          "500", "--output", str(tmp_path / "ex")], capture_output=True, text=True,
                         timeout=120, env=os.environ)
    assert out.returncode == 2 and "got 500" in out.stderr and "Traceback" not in out.stderr
    assert not (tmp_path / "ex").exists()


NARROW = """<mujoco><compiler angle="radian"/><worldbody><body name="a">
<joint name="j1" range="0 0.08" limited="true"/>
<inertial pos="0 0 0.1" mass="1" diaginertia="0.01 0.01 0.01"/></body></worldbody>
<actuator><motor joint="j1" ctrlrange="-5 5"/></actuator></mujoco>"""


def test_excite_names_a_joint_range_narrower_than_its_margins(tmp_path):
    from mbctl.jobs.excite import prepare

    path = tmp_path / "narrow.xml"
    path.write_text(NARROW)
    with pytest.raises(InvalidPlanningInput, match=_escape(
            "joint 'j1' has the range [0, 0.08] rad (0.08 rad wide); the excitation keeps 0.05 rad inside "
            "each limit, so it needs a range wider than 0.1 rad")):
        prepare(options.excite(str(path)))


def test_a_controller_model_tracks_the_same_trajectory(two_link_run, tmp_path):
    arm = (ASSETS / "two_link_arm.xml").read_text()
    (tmp_path / "two_link_arm.xml").write_text(arm.replace('mass="0.7"', 'mass="0.84"'))  # link2 +20 %
    (tmp_path / "model.xml").write_text((ASSETS / "two_link_torque.xml").read_text())
    out = tmp_path / "ctrl"
    params = options.excite("two_link_torque", duration=1.0, period=3.0, harmonics=3, plant_error=20.0,
                            controller_model=str(tmp_path / "model.xml"))
    record = run_job(EXCITE, params, out)
    assert record.exit_code == 0, record.message
    mine = json.loads((out / "report.json").read_text())["identification_log"]
    reference = json.loads((two_link_run / "report.json").read_text())["identification_log"]
    assert mine["excitation"]["condition_number"] == reference["excitation"]["condition_number"]
    assert mine["excitation"]["limit_use_q_v_tau"] == reference["excitation"]["limit_use_q_v_tau"]
    assert mine["model_fingerprint"] == reference["model_fingerprint"]  # the robot's, not the controller's
    assert any("trajectory designed on the robot's own model, the same for any --controller-model" in line
               for line in record.outcome.summary)


def test_excite_with_a_capped_loop_log_reports_every_cycles_tracking_error(two_link_run, tmp_path,
                                                                           monkeypatch):
    """The loop's log capped at 100 rows of 3000 cycles: the tracking RMS is the uncapped run's."""
    from mbctl.control import loop

    params = options.excite("two_link_torque", duration=6.0, period=3.0, harmonics=3, plant_error=20.0)
    monkeypatch.setattr(loop, "MAX_LOG_ROWS", 100)
    record = run_job(EXCITE, params, tmp_path / "capped")
    full = json.loads((two_link_run / "report.json").read_text())["values"]
    assert record.values["rows"] == full["rows"] == 3000 and record.exit_code == 0
    rms = record.values["joint_rms_error_rad"]
    assert rms > 0 and rms == pytest.approx(full["joint_rms_error_rad"], rel=1e-12, abs=0)
    assert record.values["max_torque_N_m"] == full["max_torque_N_m"]
