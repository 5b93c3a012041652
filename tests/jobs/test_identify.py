"""excite and identify as a user runs them: the 2-link hidden truth, write-back, bad logs (exit 2)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest
from typer.testing import CliRunner

from mbctl.cli import _register_commands, app
from mbctl.jobs import options
from mbctl.jobs.demo import DEMO
from mbctl.jobs.excite import EXCITE
from mbctl.jobs.identify import IDENTIFY
from mbctl.jobs.identify import prepare as prepare_identify
from mbctl.jobs.runner import run_job
from mbctl.robots.identification import BadLogError, ParameterSet
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
    from mbctl.control.exceptions import ControllerSetupError
    from mbctl.jobs.excite import prepare

    with pytest.raises(ControllerSetupError, match="has a floating base; excite runs fixed-base robots"):
        prepare(options.excite(str(path)))
