"""The ``mbctl ik`` job: task set by identity, both backends, the MuJoCo plant check, exit codes."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

import mbctl
from mbctl.control import IKSetupError
from mbctl.control.ik import QPWholeBodyIK, WholeBodyIKConfig
from mbctl.jobs.ik import IK, IKParams, plant_frames, plant_residuals, prepare
from mbctl.jobs.runner import Job, run_job
from mbctl.robots import load_robot
from mbctl.robots.g1 import FEET, PALM_SITES, PELVIS, is_menagerie_g1

ASSETS = Path(mbctl.__file__).resolve().parent / "robots" / "assets"

#: Joint-angle agreement [rad] of the qp and mink G1 poses: both meet 0.1 mm on every target,
#: but the posture regulariser (cost 1e-2) leaves the redundant dofs where each path ended; the
#: paths differ because mink's first step at zero palm rotation drops a Jlog6 block.
POSE_ATOL_RAD = 0.05


def _pose(folder: Path) -> dict:
    return json.loads((folder / "ik_pose.json").read_text())


def _q(robot, pose: dict) -> np.ndarray:
    q = np.zeros(robot.nq)
    for joint in robot.joints.values():
        q[joint.idx_q : joint.idx_q + joint.nq] = pose["q"][joint.name]
    return q


def test_mink_and_qp_give_the_same_g1_pose(g1, tmp_path):
    poses = {}
    for backend in ("qp", "mink"):
        params = IKParams("g1", targets=(("left_palm", (0.1, 0.0, 0.0)), ("right_palm", (0.1, -0.05, 0.0))),
                          com_xy=(0.0, 0.0), relative=True, tol_m=1e-4, backend=backend)
        record = run_job(IK, params, tmp_path / backend)
        assert record.exit_code == 0, record.summary()
        poses[backend] = _pose(tmp_path / backend)
        assert poses[backend]["task_set"] == "g1" and poses[backend]["backend"] == backend
        assert max(poses[backend]["plant_residual_m"].values()) < 1e-4
        assert max(poses[backend]["plant_residual_rad"].values()) < 1e-3
    assert set(poses["qp"]["plant_residual_m"]) == {*FEET, *PALM_SITES, "com"}
    assert set(poses["qp"]["plant_residual_rad"]) == {*FEET, PELVIS}
    q_qp, q_mink = _q(g1, poses["qp"]), _q(g1, poses["mink"])
    frames = (*FEET, *PALM_SITES)
    from mbctl.robots.g1 import with_palm_sites

    g1p = with_palm_sites(g1)
    qp, mink = plant_frames(g1p, q_qp, frames), plant_frames(g1p, q_mink, frames)
    for frame in frames:
        np.testing.assert_allclose(qp.positions[frame], mink.positions[frame], atol=2e-4)
    np.testing.assert_allclose(qp.com[:2], mink.com[:2], atol=2e-4)
    assert np.max(np.abs(q_qp - q_mink)) < POSE_ATOL_RAD


def test_user_file_named_g1_gets_the_generic_task_set(g1, tmp_path):
    user = tmp_path / "g1.xml"
    shutil.copy(ASSETS / "two_link_arm.xml", user)
    robot = load_robot(user)
    assert robot.name == "g1" and not is_menagerie_g1(robot)
    assert is_menagerie_g1(g1)
    for backend in ("qp", "mink"):
        params = IKParams(str(user), targets=(("end_effector", (0.3, 0.3, 0.0)),), tol_m=1e-4,
                          backend=backend)
        record = run_job(IK, params, tmp_path / backend)
        assert record.exit_code == 0, record.summary()
        pose = _pose(tmp_path / backend)
        assert pose["task_set"] == "generic" and pose["origin"].startswith("user file")
        assert pose["plant_residual_m"]["end_effector"] < 1e-4
        assert not any("palm" in e for e in pose["model_edits"])
    # the G1's palm targets are not offered to a user file, whatever it is called
    with pytest.raises(IKSetupError, match="Unknown IK frame .*'left_palm'"):
        prepare(IKParams(str(user), targets=(("left_palm", (0.3, 0.3, 0.0)),)))


def test_user_copy_of_the_menagerie_g1_is_not_the_g1(g1, tmp_path):
    robot = load_robot(g1.source.robot_file)  # the same file, loaded by path: a user file
    assert robot.name == "g1" and not is_menagerie_g1(robot)
    params = IKParams(str(g1.source.robot_file), targets=(("left_foot", (0.0, 0.0, 0.01)),),
                      relative=True, keyframe="stand", tol_m=1e-3)
    record = run_job(IK, params, tmp_path)
    pose = _pose(tmp_path)
    assert pose["task_set"] == "generic" and "left_foot" in pose["plant_residual_m"]
    assert record.exit_code == (0 if pose["converged"] else 1)


def test_plant_check_catches_a_wrong_answer(tmp_path):
    """Pinocchio's arm has a 0.35 m first link, MuJoCo's 0.3 m: the IK converges on its own model,
    the pose misses in MuJoCo, so the run is not converged and exits 1."""
    wrong = tmp_path / "longer_arm.xml"
    wrong.write_text((ASSETS / "two_link_arm.xml").read_text().replace(
        '<body name="link2" pos="0.3 0 0">', '<body name="link2" pos="0.35 0 0">'))
    robot = load_robot("two_link", pin_model_file=wrong, check=False)
    params = IKParams("two_link", targets=(("end_effector", (0.3, 0.3, 0.0)),), tol_m=1e-4)
    record = run_job(Job("ik", lambda p: prepare(p, robot)), params, tmp_path / "run")
    assert record.exit_code == 1 and record.outcome is not None and not record.outcome.passed
    pose = _pose(tmp_path / "run")
    assert pose["ik_converged"] is True and pose["converged"] is False
    assert pose["plant_residual_m"]["end_effector"] > 1e-2  # about the 5 cm link error
    assert "the MuJoCo plant disagrees" in record.summary()
    assert "plant check: largest residual in MuJoCo" in record.summary()


def test_plant_check_catches_a_wrong_orientation(tmp_path):
    """Pinocchio's end-effector site is turned 0.2 rad about z, MuJoCo's is not: a held frame's
    orientation agrees with the IK's own target and misses on the plant by the 0.2 rad."""
    turned = tmp_path / "turned_site.xml"
    turned.write_text((ASSETS / "two_link_arm.xml").read_text().replace(
        '<site name="end_effector" pos="0.015 0 0"',
        '<site name="end_effector" pos="0.015 0 0" quat="0.99500417 0 0 0.09983342"'))
    robot = load_robot("two_link", pin_model_file=turned, check=False)
    q = np.array([0.3, 0.5])
    ik = QPWholeBodyIK(robot, WholeBodyIKConfig(held_frames=("end_effector",)), q)
    assert ik.task_residuals()["end_effector"].orientation_rad < 1e-12
    plant = plant_residuals(robot, ik, q)
    assert plant.position_m["end_effector"] < 1e-12
    assert plant.orientation_rad["end_effector"] == pytest.approx(0.2, abs=1e-6)
    assert not plant.within(1e-3, 1e-2) and plant.within(1e-3, 0.21)


def test_generic_com_on_a_scene_qp_converges_and_mink_says_why_it_cannot(tmp_path):
    """A scene that puts a (massless) body before the robot: mink's ComTask would hold that
    body's subtree CoM, so the mink backend refuses, naming the body; qp holds the robot's CoM."""
    shutil.copy(ASSETS / "two_link_arm.xml", tmp_path / "arm.xml")
    (tmp_path / "scene.xml").write_text(
        '<mujoco model="arm_scene"><worldbody><body name="marker" pos="1 0 0"/></worldbody>'
        '<include file="arm.xml"/></mujoco>')
    params = {"robot": str(tmp_path / "arm.xml"), "scene": str(tmp_path / "scene.xml"),
              "com_xy": (0.1, 0.2), "tol_m": 1e-4}
    with pytest.raises(IKSetupError, match="mink's ComTask uses the subtree of MuJoCo body 1, and MuJoCo "
                                           r"body 1 \('marker', 0 kg\) is not the robot's.* use backend 'qp'"):
        prepare(IKParams(**params, backend="mink"))
    # (without the per-joint trust region, the first step from the straight arm spun the
    # unlimited joints by ~150 rad and the posture regulariser left the CoM 2 mm off)
    record = run_job(IK, IKParams(**params, backend="qp"), tmp_path / "qp")
    assert record.exit_code == 0, record.summary()
    pose = _pose(tmp_path / "qp")
    assert pose["plant_residual_m"]["com"] < 1e-4 and pose["iterations"] <= 10


def test_model_dir_only_where_it_applies(tmp_path):
    with pytest.raises(IKSetupError, match="--model-dir applies only to a known robot"):
        IKParams(str(tmp_path / "arm.xml"), targets=(("end_effector", (0.3, 0.3, 0.0)),),
                 model_dir=str(tmp_path))


def test_unreachable_target_exits_1_with_the_closest_pose(two_link, tmp_path):
    params = IKParams("two_link", targets=(("end_effector", (1.0, 0.0, 0.0)),), max_iters=30)
    record = run_job(IK, params, tmp_path)
    assert record.exit_code == 1
    pose = _pose(tmp_path)
    assert pose["converged"] is False
    assert pose["plant_residual_m"]["end_effector"] == pytest.approx(1.0 - 0.615, abs=5e-3)


def test_singular_start_is_not_passed_off_as_the_closest_pose(two_link, tmp_path):
    """(0.05, 0, 0) is reachable (r_min = 0.015 m), but from the straight arm the error lies in
    the Jacobian's null space: the step vanishes, the run exits 1 and says the start may be singular."""
    record = run_job(IK, IKParams("two_link", targets=(("end_effector", (0.05, 0.0, 0.0)),)), tmp_path)
    assert record.exit_code == 1
    assert "start pose is singular" in record.summary() and "closest" not in record.summary()
    assert _pose(tmp_path)["stalled"] is True


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"backend": "pink"}, "backend must be one of qp, mink; got 'pink'"),
    ({"solver": "cvxopt"}, "solver must be one of daqp, osqp"),
    ({"tol_m": 0.0}, "tol must be a positive length"),
    ({"targets": ()}, "Give at least one --target"),
])
def test_bad_parameters_name_the_value(kwargs, message):
    base = {"robot": "two_link", "targets": (("end_effector", (0.3, 0.3, 0.0)),)}
    with pytest.raises(IKSetupError, match=message):
        IKParams(**{**base, **kwargs})


def test_unknown_frame_lists_close_matches(two_link):
    with pytest.raises(IKSetupError, match="Did you mean 'end_effector'"):
        prepare(IKParams("two_link", targets=(("end_efector", (0.3, 0.3, 0.0)),)))
