"""The G1 on its feet: a payload hidden on the torso, found from joint torques alone (short log)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mbctl.jobs import options
from mbctl.jobs.excite import EXCITE
from mbctl.jobs.identify import IDENTIFY
from mbctl.jobs.runner import run_job
from mbctl.robots.identification import ParameterSet
from mbctl.robots.identification.inertial import to_inertial
from mbctl.robots.registry import load_robot

PAYLOAD = "2.0@torso_link:0.05,0,0.25"


@pytest.fixture(scope="module")
def g1_run(g1, tmp_path_factory):
    out = tmp_path_factory.mktemp("excite_g1") / "run"
    params = options.excite("g1", duration=3.0, period=4.0, harmonics=2, payload=PAYLOAD)
    record = run_job(EXCITE, params, out)
    assert record.exit_code == 0, record.message
    return out


def test_the_log_has_what_identification_needs(g1_run):
    report = json.loads((g1_run / "report.json").read_text())
    section = report["identification_log"]
    assert section["contact_bodies"] == ["left_ankle_roll_link", "right_ankle_roll_link"]
    assert len(section["joints"]) == 29 and section["robot"] == "g1"
    header = (g1_run / "excite.csv").read_text().splitlines()[0].split(",")
    for column in ("contact_left_ankle_roll_link", "w_right_ankle_roll_link_fz_N", "other_contacts",
                   "tau_left_knee_joint_N_m", "floating_base_joint_qw", "v_waist_pitch_joint_rad_s"):
        assert column in header
    assert report["values"]["fell"] is False and report["values"]["samples_with_other_contacts"] == 0


def _torso_with_payload(plant):
    """The plant's torso and payload as one body, in the torso's frame: the hidden truth."""
    params = ParameterSet(plant, ["torso_link", "payload_torso_link"])
    torso, payload = params.body("torso_link"), params.body("payload_torso_link")
    in_joint = torso.transform @ torso.nominal + payload.transform @ payload.nominal
    return np.linalg.solve(torso.transform, in_joint)


def test_torso_payload_identified_from_joint_torques(g1_run, tmp_path):
    record = run_job(IDENTIFY, options.identify([str(g1_run)], bodies="torso_link"), tmp_path / "id")
    assert record.exit_code == 0, record.message
    report = json.loads((tmp_path / "id" / "identify_report.json").read_text())
    assert report["method"]["contacts"].startswith("projected onto the null space of the contact Jacobian")
    assert report["logs"][0]["interface"] == "sim" and report["logs"][0]["torques"].startswith("applied")
    truth = to_inertial(_torso_with_payload(load_robot(g1_run / "model.xml")))
    torso = report["bodies"]["torso_link"]
    assert abs(torso["mass_kg"]["identified"] - truth.mass_kg) < 0.1
    assert abs(truth.mass_kg - torso["mass_kg"]["nominal"] - 2.0) < 1e-9
    assert np.linalg.norm(np.array(torso["com_m"]["identified"]) - truth.com_m) < 0.01
    assert report["validation"]["torque_rmse_identified"] < 0.5 * report["validation"]["torque_rmse_nominal"]
    assert report["identified_model"]["xcheck_max_rel_error"] < 1e-9
