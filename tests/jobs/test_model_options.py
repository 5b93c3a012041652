"""--payload, --plant-error and --controller-model: the plant's hidden truth and the controller's model."""

from __future__ import annotations

import numpy as np
import pytest

from mbctl.jobs import options
from mbctl.jobs.joint_step import JOINT_STEP
from mbctl.jobs.model_options import ModelOptionError, ModelOptions, Payload, build_models, parse_payload
from mbctl.jobs.runner import run_job
from mbctl.robots.edits import standalone_xml
from mbctl.robots.exceptions import UnknownNameError


@pytest.mark.parametrize("text, payload", [
    ("2.0@torso_link:0.05,0,0.25", Payload(2.0, "torso_link", (0.05, 0.0, 0.25))),
    ("0.5@ee_body", Payload(0.5, "ee_body", (0.0, 0.0, 0.0))),
])
def test_payload_parses(text, payload):
    assert parse_payload(text) == payload


@pytest.mark.parametrize("text, message", [
    ("2.0", "must look like KG@BODY"), ("x@b", "the mass 'x' is not a number"), ("-1@b", "mass must be > 0"),
    ("1@b:1,2", "offset must be X,Y,Z"), ("1@:1,2,3", "must look like KG@BODY"),
    # an offset of 1e9 m failed later, as the load-time agreement check's FK difference
    ("1@b:1e9,0,0", r"offset \[1000000000.0, 0.0, 0.0\] m is 1e\+09 m from its body; .* at most 10 m"),
])
def test_bad_payloads_are_refused(text, message):
    with pytest.raises(ModelOptionError, match=message):
        ModelOptions(payload=text)


def test_plant_gets_the_hidden_truth_and_the_controller_does_not(two_link_torque_gravity):
    hidden = ModelOptions(payload="0.3@link2:0.1,0,0", plant_error=10.0)
    models = build_models(two_link_torque_gravity, hidden)
    plant_mass = sum(i.mass for i in models.plant.pin_model.inertias)
    nominal_mass = sum(i.mass for i in two_link_torque_gravity.pin_model.inertias)
    assert plant_mass == pytest.approx(1.1 * (nominal_mass + 0.3))  # the payload is a plant link too
    assert models.controller is two_link_torque_gravity
    assert models.section() == {"payload": "0.3@link2:0.1,0,0", "plant_error_pct": 10.0,
                                "controller_model": "the robot's own"}
    with pytest.raises(UnknownNameError, match="Did you mean 'link2'"):
        build_models(two_link_torque_gravity, ModelOptions(payload="1@link3"))


def test_a_payload_heavier_than_1000_robots_is_refused(two_link_torque_gravity):
    """``--payload 1e30@link2`` made a plant (and a run) with a 1e30 kg point mass on a 1.75 kg arm."""
    from mbctl.robots.exceptions import RobotError

    robot_mass = float(np.sum(two_link_torque_gravity.mj_model.body_mass))
    assert robot_mass == pytest.approx(1.75)
    with pytest.raises(RobotError, match=r"payload mass 1e\+30 kg is more than 1000 times the robot's own "
                                         r"mass \(1.75 kg\): at most 1750 kg for 'two_link_torque'"):
        build_models(two_link_torque_gravity, ModelOptions(payload="1e30@link2"))
    heaviest = build_models(two_link_torque_gravity, ModelOptions(payload="1750@link2"))
    assert sum(i.mass for i in heaviest.plant.pin_model.inertias) == pytest.approx(1751.75)


def test_controller_model_from_a_file_of_the_same_robot(two_link_torque_gravity, two_link_torque, tmp_path):
    path = tmp_path / "model.xml"
    path.write_text(standalone_xml(two_link_torque))  # gravity off in the file: the plant's is used
    models = build_models(two_link_torque_gravity, ModelOptions(controller_model=str(path)))
    np.testing.assert_allclose(models.controller_model.gravity.linear, [0.0, -9.81, 0.0])
    other = tmp_path / "other.xml"
    other.write_text('<mujoco><worldbody><body name="b"><joint name="hinge"/><inertial pos="0 0 0" mass="1" '
                     'diaginertia="1 1 1"/></body></worldbody></mujoco>')
    with pytest.raises(ModelOptionError, match=r"missing \['shoulder', 'elbow'\], extra \['hinge'\]"):
        build_models(two_link_torque_gravity, ModelOptions(controller_model=str(other)))
    with pytest.raises(ModelOptionError, match="is not a file"):
        ModelOptions(controller_model=str(tmp_path / "nothing.xml"))


def test_joint_step_records_the_plant_options(tmp_path):
    params = options.joint_step("two_link", "elbow", 0.1, steps=20, payload="0.2@ee_body")
    record = run_job(JOINT_STEP, params, tmp_path)
    assert record.exit_code == 0
    assert "payload 0.2@ee_body" in record.summary() and "not used" in record.summary()
