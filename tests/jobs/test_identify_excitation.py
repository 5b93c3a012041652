"""``mbctl identify`` says which numbers the log barely excited, in its summary and its report."""

from __future__ import annotations

import json

import pytest

from mbctl.jobs import options
from mbctl.jobs.excite import EXCITE
from mbctl.jobs.identify import IDENTIFY
from mbctl.jobs.runner import run_job

#: A cart on a short vertical slide carrying an arm that may swing only +-0.35 rad about hanging
#: sideways: its CoM's z lever (along the arm's hanging direction) is barely excited.
LIFT = """<mujoco><compiler angle="radian"/><option gravity="0 0 -9.81"/><worldbody><body name="cart">
<joint name="lift" type="slide" axis="0 0 1" range="-0.1 0.1"/>
<inertial pos="0 0 0" mass="2" diaginertia="0.01 0.01 0.01"/><body name="arm">
<joint name="swing" axis="0 1 0" range="-0.35 0.35"/>
<inertial pos="0.1 0 0.02" mass="1" diaginertia="0.001 0.01 0.01"/></body></body></worldbody>
<actuator><motor joint="lift" ctrlrange="-100 100"/><motor joint="swing" ctrlrange="-20 20"/></actuator>
</mujoco>"""


@pytest.fixture(scope="module")
def identified(tmp_path_factory):
    root = tmp_path_factory.mktemp("lift")
    (root / "lift.xml").write_text(LIFT)
    record = run_job(EXCITE, options.excite(str(root / "lift.xml"), duration=10.0), root / "excite")
    assert record.exit_code == 0, record.message
    record = run_job(IDENTIFY, options.identify([str(root / "excite")], bodies="arm"), root / "identify")
    assert record.exit_code == 0, record.message
    return record, json.loads((root / "identify" / "identify_report.json").read_text())


def test_the_summary_marks_the_weakly_excited_com_coordinate(identified):
    record, _ = identified
    lines = record.summary().splitlines()
    arm = next(line for line in lines if line.startswith("  arm: mass"))
    assert arm.endswith("m (y: not identified; z: weakly excited)"), arm
    assert "weakly excited (the log barely moves them; trust them only within their std): arm.mcz, arm.Iyy" \
        in lines


def test_the_report_gives_each_number_its_status(identified):
    _, report = identified
    arm = report["bodies"]["arm"]
    assert arm["mass_kg"]["status"] == "identified"
    assert arm["com_m"]["status"] == ["identified", "not identified", "weakly excited"]
    assert report["identifiability"]["weakly_excited"] == ["arm.mcz", "arm.Iyy"]
    base = {b["expression"]: b for b in report["identifiability"]["base_parameters"]}
    assert base["arm.mcz"]["status"] == "weakly excited" and base["arm.m"]["status"] == "identified"
    assert 0 < base["arm.m"]["std"] < 1e-3  # kg: an exact log, the mass weighed by the slide
    assert "residual-aware" in report["method"]["std"]
