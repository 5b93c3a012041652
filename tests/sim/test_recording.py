"""Recorder, JSON report, and the joint-step job."""

from __future__ import annotations

import json
import os
from functools import partial

import numpy as np
import pytest

from mbctl.jobs.joint_step import JointStepParams, prepare
from mbctl.jobs.runner import Job, run_job
from mbctl.robots import UnknownNameError
from mbctl.robots.edits import position_to_motor
from mbctl.robots.exceptions import CommandError
from mbctl.robots.menagerie import sha256_file
from mbctl.sim import Simulator, torque
from mbctl.sim.atomic import write_json_atomic
from mbctl.sim.recorder import Recorder, joint_columns, read_csv, sensor_columns, time_column
from mbctl.sim.report import environment, model_section, run_section


def test_recording_survives_an_error_mid_run(two_link_torque, tmp_path):
    sim = Simulator(two_link_torque)
    path = tmp_path / "run.csv"
    columns = [time_column(), *joint_columns(sim, ["shoulder", "elbow"]), *sensor_columns(sim, ["ee_pos"])]
    with pytest.raises(CommandError):
        with Recorder(path, columns) as rec:
            for _ in range(5):
                sim.step(torque([1.0, 0.5]))
                rec.record(sim)
            sim.step(torque([np.nan, 0.0]))  # raises mid-run
    data = read_csv(path)
    assert list(data) == ["time_s", "q_shoulder_rad", "q_elbow_rad", "ee_pos[0]", "ee_pos[1]", "ee_pos[2]"]
    np.testing.assert_allclose(data["time_s"], 0.002 * np.arange(1, 6))
    assert data["q_elbow_rad"][-1] != 0.0
    assert sorted(os.listdir(tmp_path)) == ["run.csv"]  # no temporary file left


def test_rows_are_on_disk_as_they_are_recorded(two_link_torque, tmp_path):
    sim = Simulator(two_link_torque)
    rec = Recorder(tmp_path / "a.csv", [time_column()])
    rec.record(sim)
    sim.step(torque([0.0, 0.0]))
    rec.record(sim)
    # before close: a reader already sees the header and both complete rows
    assert (tmp_path / "a.csv").read_text().splitlines() == ["time_s", "0.0", "0.002"]
    rec.close()
    assert rec.rows == 2


def test_atomic_file_is_not_published_when_the_block_raises(tmp_path):
    from mbctl.sim.atomic import AtomicFile

    (tmp_path / "r.json").write_text("old")
    with pytest.raises(KeyboardInterrupt):
        with AtomicFile(tmp_path / "r.json") as f:
            f.file.write("half")
            raise KeyboardInterrupt
    assert (tmp_path / "r.json").read_text() == "old"  # the previous file, never a torn new one
    assert sorted(os.listdir(tmp_path)) == ["r.json"]


def test_report_contents(two_link_torque, tmp_path):
    sim = Simulator(two_link_torque)
    sim.step(torque([50.0, 0.0]), 10)
    report = {"environment": environment(), "model": model_section(sim), "run": run_section(sim),
              "values": {"x": float("nan")}}
    path = write_json_atomic(tmp_path / "r.json", report)
    loaded = json.loads(path.read_text())
    assert loaded["model"]["timestep_s"] == 0.002
    assert loaded["model"]["integrator"] == "IMPLICITFAST"
    assert loaded["run"]["steps"] == 10
    assert loaded["run"]["simulated_time_s"] == pytest.approx(0.02)
    assert loaded["run"]["saturations"] == {"shoulder": 1}
    assert loaded["values"]["x"] is None  # NaN is written as null, the file stays valid JSON
    files = loaded["model"]["files"]
    assert files["scene"]["sha256"] == sha256_file(two_link_torque.source.scene_file)
    assert loaded["environment"]["packages"]["mujoco"].startswith("4.")


def _joint_step(robot, tmp_path, joint, delta, steps, **kw):
    params = JointStepParams(robot.name, joint, delta, steps, **kw)
    return run_job(Job("joint-step", partial(prepare, robot=robot)), params, tmp_path)


def test_joint_step_g1(g1, tmp_path):
    record = _joint_step(g1, tmp_path, "left_elbow_joint", 0.1, 250, keyframe="stand",
                         sensors=("imu-pelvis-angular-velocity",))
    values = record.values
    assert values["before_rad"] == pytest.approx(1.28)
    assert values["target_rad"] == pytest.approx(1.38)
    assert abs(values["final_rad"] - values["target_rad"]) < 2e-3
    assert abs(values["base_z_final_m"] - 0.79) < 0.02
    assert values["simulated_time_s"] == pytest.approx(0.5)
    data = read_csv(record.files["csv"])
    assert len(data["time_s"]) == 251 == record.rows
    assert np.all(data["ctrl_left_elbow_joint_position"] == pytest.approx(1.38))
    assert "imu-pelvis-angular-velocity[2]" in data
    report = json.loads(record.report_path.read_text())
    assert report["status"] == "completed"
    assert report["values"]["target_rad"] == pytest.approx(1.38)
    assert report["model"]["files"]["robot"]["path"].endswith("g1.xml")


def test_joint_step_two_link_without_keyframe(two_link, tmp_path):
    values = _joint_step(two_link, tmp_path, "elbow", -0.2, 300).values
    assert values["target_rad"] == pytest.approx(-0.2)
    assert abs(values["final_rad"] + 0.2) < 1e-3
    assert np.isnan(values["base_z_final_m"])


def test_joint_step_bad_input(g1, tmp_path):
    out = tmp_path / "never"
    with pytest.raises(UnknownNameError, match="Did you mean 'left_elbow_joint'"):
        _joint_step(g1, out, "left_elbow", 0.1, 10)
    with pytest.raises(UnknownNameError, match="Unknown sensor 'imu'"):
        _joint_step(g1, out, "left_elbow_joint", 0.1, 10, sensors=("imu",))
    with pytest.raises(CommandError, match="needs a position actuator"):
        _joint_step(position_to_motor(g1), out, "left_elbow_joint", 0.1, 10)
    with pytest.raises(CommandError, match="steps must be >= 1"):
        JointStepParams("g1", "left_elbow_joint", 0.1, 0)
    assert not list(out.iterdir())  # bad input: nothing written, no lock left
