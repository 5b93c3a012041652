"""The ``mbctl ik`` job: task set by identity, both backends, the MuJoCo plant check, exit codes."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import mbctl
from mbctl.control import IKSetupError
from mbctl.control.ik import QPWholeBodyIK, WholeBodyIKConfig
from mbctl.control.tasks import Tolerance, converged
from mbctl.jobs.ik import IK, IKParams, g1_config, plant_frames, plant_residuals, prepare
from mbctl.jobs.ik_params import TargetSpec
from mbctl.jobs.runner import Job, run_job
from mbctl.robots import load_robot
from mbctl.robots.g1 import FEET, PALM_SITES, PELVIS, is_menagerie_g1, with_palm_sites

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
    residuals = plant.task_residuals()
    assert not converged(residuals, Tolerance(1e-3, 1e-2)) and converged(residuals, Tolerance(1e-3, 0.21))


def test_generic_com_on_a_scene_qp_converges_and_mink_says_why_it_cannot(tmp_path):
    """A scene that puts a (massless) body before the robot: mink's ComTask would hold that
    body's subtree CoM, so the mink backend refuses, naming the body; qp holds the robot's CoM."""
    shutil.copy(ASSETS / "two_link_arm.xml", tmp_path / "arm.xml")
    (tmp_path / "scene.xml").write_text(
        '<mujoco model="arm_scene"><worldbody><body name="marker" pos="1 0 0"/></worldbody>'
        '<include file="arm.xml"/></mujoco>')
    params = {"robot": str(tmp_path / "arm.xml"), "scene": str(tmp_path / "scene.xml"),
              "com_xy": (0.1, 0.2), "tol_m": 1e-4}
    with pytest.raises(IKSetupError, match="mink's ComTask uses the subtree of MuJoCo body 1, and "
                                           r"MuJoCo body 1 \('marker', 0 kg\) is not the robot's.* "
                                           "use backend 'qp'"):
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


def test_collision_free_is_null_when_no_pair_is_checked(two_link, tmp_path):
    """A robot without a default collision set, no pair named: nothing was measured, so
    ``collision_free`` is null (it was ``true``, for poses whose arms interpenetrate too); the G1
    tests below show a checked run's boolean."""
    record = run_job(IK, IKParams("two_link", targets=(("end_effector", (0.3, 0.3, 0.0)),)), tmp_path)
    pose = _pose(tmp_path)
    assert record.exit_code == 0 and pose["converged"] is True
    assert pose["collision_free"] is None and record.values["collision_free"] is None
    assert pose["collision_pairs_checked"] == 0 and "collision check: none" in record.summary()


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


# ---------------------------------------------------------------------- the body, the start, targets
CROSSED = (("left_palm", (0.28, -0.12, 0.95)), ("right_palm", (0.28, 0.12, 0.95)))


def test_crossed_palms_are_not_converged_through_the_elbows(g1, tmp_path):
    """The issue's case: without avoidance the IK meets both palm targets with the forearms inside
    each other; the plant check measures the body at every step and refuses the claim."""
    record = run_job(IK, IKParams("g1", targets=CROSSED), tmp_path / "plain")
    assert record.exit_code == 1
    pose = _pose(tmp_path / "plain")
    assert pose["ik_converged"] is True and pose["converged"] is False and pose["collision_free"] is False
    assert pose["min_distance_m"] < -0.05 and "elbow" in pose["closest_pair"]
    assert "the path goes through the body" in record.summary() and "--avoid-collisions" in record.summary()
    assert record.values["min_distance_m"] == pose["min_distance_m"]
    # with avoidance: the forearms pass each other, every step stays >= 5 mm apart in MuJoCo
    record = run_job(IK, IKParams("g1", targets=CROSSED, avoid_collisions=True), tmp_path / "avoid")
    pose = _pose(tmp_path / "avoid")
    assert record.exit_code == 0, record.summary()
    assert pose["collision_free"] is True and min(pose["path_min_distance_m"]) >= 0.005
    assert max(pose["plant_residual_m"].values()) < 1e-3


def test_a_palm_target_inside_the_torso_ends_at_the_closest_collision_free_pose(g1, tmp_path):
    for backend in ("qp", "mink"):
        params = IKParams("g1", targets=(("left_palm", (0.03, 0.0, 1.0)),), avoid_collisions=True,
                          backend=backend)
        record = run_job(IK, params, tmp_path / backend)
        pose = _pose(tmp_path / backend)
        assert record.exit_code == 1 and pose["converged"] is False
        if backend == "qp":  # our step guard: the closest collision-free pose, never through the body
            assert "blocked by collision avoidance" in record.summary()
            assert pose["collision_free"] is True and pose["min_distance_m"] >= 0.005
            assert pose["path_min_distance_m"][-1] < 0.006


def test_collision_pairs_by_name_and_their_errors(g1, tmp_path):
    params = IKParams("g1", targets=CROSSED, collision_pairs=("left_elbow_link:right_elbow_link",),
                      min_distance_m=0.02)
    record = run_job(IK, params, tmp_path)
    pose = _pose(tmp_path)
    assert pose["collision_pairs_checked"] == 1 and pose["closest_pair"] == "left_elbow_link/right_elbow_link"
    assert min(pose["path_min_distance_m"]) >= 0.02 and record.values["collision_free"] is True
    with pytest.raises(IKSetupError, match="Did you mean 'left_elbow_link'"):
        prepare(IKParams("g1", targets=CROSSED, collision_pairs=("left_elbw_link:torso_link",)))
    with pytest.raises(IKSetupError, match="a collision pair is A:B"):
        IKParams("g1", targets=CROSSED, collision_pairs=("left_elbow_link",))
    with pytest.raises(IKSetupError, match="min distance must be in"):
        IKParams("g1", targets=CROSSED, min_distance_m=1.0)


def test_robot_com_not_the_scenes_mocap_targets(tmp_path):
    """3.7 kg of mocap target bodies after the robot: the plant check compares the robot's CoM (not
    subtree_com[0], the whole plant's), and mink's ComTask is fine: body 1 is the robot's root."""
    shutil.copy(ASSETS / "two_link_arm.xml", tmp_path / "arm.xml")
    (tmp_path / "scene.xml").write_text(
        '<mujoco model="arm_targets"><include file="arm.xml"/><worldbody>'
        '<body name="goal_a" mocap="true" pos="0.4 0.4 0"><geom type="sphere" size="0.05"/>'
        '<inertial pos="0 0 0" mass="2.2" diaginertia="0.01 0.01 0.01"/></body>'
        '<body name="goal_b" mocap="true" pos="-0.3 0.5 0"><geom type="box" size="0.05 0.05 0.05"/>'
        '<inertial pos="0 0 0" mass="1.5" diaginertia="0.01 0.01 0.01"/></body></worldbody></mujoco>')
    robot = load_robot(tmp_path / "arm.xml", tmp_path / "scene.xml")
    assert float(robot.mj_model.body_subtreemass[0]) == pytest.approx(1.75 + 3.7)
    for backend in ("qp", "mink"):
        params = IKParams(str(tmp_path / "arm.xml"), scene=str(tmp_path / "scene.xml"), com_xy=(0.1, 0.2),
                          tol_m=1e-4, backend=backend)
        record = run_job(IK, params, tmp_path / backend)
        assert record.exit_code == 0, record.summary()
        assert _pose(tmp_path / backend)["plant_residual_m"]["com"] < 1e-4
    frames = plant_frames(robot, _q(robot, _pose(tmp_path / "qp")), ())
    assert np.linalg.norm(frames.com[:2] - [0.1, 0.2]) < 1e-4


#: A 3-dof arm with a "home" keyframe inside its limits and a "bent" one outside them.
HOMED = """
<mujoco model="homed">
  <compiler angle="radian" autolimits="true"/>
  <worldbody>
    <body name="l1"><joint name="j1" axis="0 0 1" range="-1 1"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02"/>
      <body name="l2" pos="0.3 0 0"><joint name="j2" axis="0 0 1" range="0 2"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02"/>
        <body name="l3" pos="0.3 0 0"><joint name="j3" axis="0 1 0" range="-0.5 0.5"/>
          <geom type="capsule" fromto="0 0 0 0.1 0 0" size="0.02"/><site name="tip" pos="0.1 0 0"/>
        </body>
      </body>
    </body>
  </worldbody>
  <keyframe><key name="home" qpos="0.2 0.8 0"/><key name="bent" qpos="1.3 0.8 -0.6"/></keyframe>
</mujoco>
"""


def test_start_from_home_and_outside_the_joint_limits(tmp_path):
    path = tmp_path / "homed.xml"
    path.write_text(HOMED)
    record = run_job(IK, IKParams(str(path), targets=(("tip", (0.0, 0.02, 0.0)),), relative=True),
                     tmp_path / "a")
    assert record.exit_code == 0, record.summary()
    assert _pose(tmp_path / "a")["start"] == "keyframe 'home'"
    assert "start: keyframe 'home'" in record.summary()
    with pytest.raises(IKSetupError, match=r"start \(keyframe 'bent'\) is outside the joint limits: "
                                           r"j1 at 1.3000 \(limits \[-1.0000, 1.0000\], 0.3000 outside\); "
                                           r"j3 at -0.6000 .*"
                                           r"0.1000 outside.*--clip-start"):
        prepare(IKParams(str(path), targets=(("tip", (0.0, 0.02, 0.0)),), relative=True, keyframe="bent"))
    params = IKParams(str(path), targets=(("tip", (0.0, -0.02, 0.0)),), relative=True, keyframe="bent",
                      clip_start=True)  # j1 at its upper limit after clipping: a target it can reach
    record = run_job(IK, params, tmp_path / "b")
    pose = _pose(tmp_path / "b")
    assert pose["clipped_start"] == pytest.approx({"j1": 0.3, "j3": 0.1})
    assert record.exit_code == 0
    assert "clipped into the joint limits (j1 by 0.3000, j3 by 0.1000)" in record.summary()
    # a robot without "home" starts from its neutral pose, and says so
    no_home = tmp_path / "no_home.xml"
    no_home.write_text(HOMED.replace('name="home"', 'name="other"'))
    run_job(IK, IKParams(str(no_home), targets=(("tip", (0.3, 0.3, 0.0)),)), tmp_path / "c")
    assert _pose(tmp_path / "c")["start"] == "the neutral pose (no 'home' keyframe)"


def test_full_pose_and_relative_targets_are_met_on_the_plant(g1, tmp_path):
    """A palm pose (position and quaternion) in the world, the other palm's pose in the torso frame."""
    turn = pin.Quaternion(pin.exp3(np.array([0.0, 0.0, 0.4]))).normalized()  # 0.4 rad about z
    robot = with_palm_sites(g1)
    data = robot.pin_model.createData()
    pin.framesForwardKinematics(robot.pin_model, data, robot.keyframe_q("stand"))
    X_WL = data.oMf[robot.pin_model.getFrameId("left_palm")]
    X_WT = data.oMf[robot.pin_model.getFrameId("torso_link")]
    X_TR = X_WT.actInv(data.oMf[robot.pin_model.getFrameId("right_palm")])
    q_left = pin.Quaternion(X_WL.rotation) * turn
    left = TargetSpec("left_palm", tuple(X_WL.translation + [0.05, 0.0, 0.05]),
                      (q_left.w, q_left.x, q_left.y, q_left.z))
    right = TargetSpec("right_palm", tuple(X_TR.translation + [0.05, 0.0, 0.0]), reference="torso_link")
    # (without avoidance this pose puts the right wrist 12 mm into the hip: the plant check says so)
    record = run_job(IK, IKParams("g1", poses=(left, right), tol_m=1e-4, avoid_collisions=True), tmp_path)
    pose = _pose(tmp_path)
    assert record.exit_code == 0, record.summary()
    assert pose["plant_residual_rad"]["left_palm"] < 1e-3 and pose["plant_residual_m"]["right_palm"] < 1e-4
    assert "right_palm" not in pose["plant_residual_rad"]  # a relative position target only


@pytest.mark.parametrize(("text", "message"), [
    ("left_palm@=0.1,0,0", "FRAME@REF needs both names"),
    ("left_palm=0.1,0,0,0,0,0,0", "quaternion QW,QX,QY,QZ must not be zero"),
    ("left_palm=0.1,0,0,1", "must be 3 or 7 finite numbers"),
])
def test_target_text_errors(text, message):
    from mbctl.jobs.ik_params import parse_target

    with pytest.raises(IKSetupError, match=message):
        parse_target(text)


def test_an_empty_reference_or_an_implausible_damping_is_refused():
    """``--orientation left_palm@=...`` meant the world, and ``--damping 1e12`` ended in a QP
    failure that never named the damping: both are refused, naming the value."""
    from mbctl.jobs import options
    from mbctl.jobs.ik_params import MAX_DAMPING_COST, parse_orientation

    empty = "left_palm@=1,0,0,0"
    with pytest.raises(IKSetupError, match=f"--orientation FRAME@REF needs both names .* got '{empty}'"):
        parse_orientation(empty)
    assert parse_orientation("left_palm @ torso_link=1,0,0,0").reference == "torso_link"
    assert parse_orientation("left_palm=1,0,0,0").reference is None
    target = ["left_palm=0.3,0.25,0.9"]
    with pytest.raises(IKSetupError, match=r"--damping must be a weight in \[0, 100\] .*got 1000000000000.0"):
        options.ik("g1", target=target, damping=1e12)
    with pytest.raises(IKSetupError, match="--damping must be a weight in"):
        options.ik("g1", target=target, damping=-1.0)
    assert options.ik("g1", target=target, damping=MAX_DAMPING_COST).damping_cost == 100.0


def test_option_values_parse_into_the_parameters():
    from mbctl.jobs import options

    params = options.ik("g1", target=["left_palm@torso_link=0.3,0.1,0", "right_palm=0.3,-0.2,0.9,1,0,0,0"],
                        orientation=["left_palm@torso_link=0,0,0,2"], com="0,0,0.7", priority=["com=0",
                        "left_palm=1"], avoid_collisions=True, collision_pair=["robot:scene"],
                        max_velocity=["left_elbow_joint=1.5"], damping=1e-3, clip_start=True)
    left = next(s for s in params.specs if s.frame == "left_palm")
    assert left == TargetSpec("left_palm", (0.3, 0.1, 0.0), (0.0, 0.0, 0.0, 1.0), "torso_link")
    assert params.com_xy == (0.0, 0.0, 0.7) and params.priorities == (("com", 0), ("left_palm", 1))
    assert params.max_velocities == (("left_elbow_joint", 1.5),) and params.avoids and params.clip_start
    with pytest.raises(IKSetupError, match="the level must be an integer"):
        options.ik("g1", target=["left_palm=0,0,1"], priority=["com=high"])
    with pytest.raises(IKSetupError, match="must be > 0"):
        options.ik("g1", target=["left_palm=0,0,1"], max_velocity=["left_elbow_joint=-1"])
    with pytest.raises(IKSetupError, match="more than one orientation target"):
        options.ik("g1", target=["left_palm=0,0,1,1,0,0,0"], orientation=["left_palm=0,1,0,0"])


def test_com_priority_alone_puts_every_other_task_below_it(g1, tmp_path):
    """``--priority com=0`` alone: the tasks not named go one level below (level 1), so the CoM is
    met in the plant (0.5 um); before, they went to level 0 with the CoM, one weighted level, and
    the palm's pull left the CoM 82.6 mm from its target."""
    params = IKParams("g1", targets=(("left_palm", (0.9, 0.3, 1.0)),), com_xy=(0.0, 0.0),
                      priorities=(("com", 0),))
    record = run_job(IK, params, tmp_path)
    assert record.exit_code == 1  # the palm is out of reach
    pose = _pose(tmp_path)
    assert pose["plant_residual_m"]["com"] < 1e-5  # 82.6e-3 m with the unnamed tasks at level 0
    assert [level["tasks"] for level in pose["levels"]] == [
        ["com"], ["left_foot", "right_foot", "left_palm", "right_palm", "pelvis", "posture"]]
    assert pose["unnamed_tasks_level"] == 1
    assert "tasks not named by --priority at level 1" in record.summary()


def test_unreachable_palm_under_a_level_0_com_holds_the_com_in_the_plant(g1, tmp_path):
    """The palm cannot reach 0.9 m ahead without the CoM leaving the feet's x-y: with the CoM (and
    every task but the palm) at level 0 the plant's CoM stays within 1e-4 m of its target, and the
    palm still gets as close as a near-hard weighted CoM (1000 times the usual weight) lets it."""
    target = (0.9, 0.3, 1.0)
    level_0 = (*FEET, "right_palm", PELVIS, "com")
    params = IKParams("g1", targets=(("left_palm", target),), com_xy=(0.0, 0.0),
                      priorities=(*((task, 0) for task in level_0), ("left_palm", 1)), max_iters=80)
    record = run_job(IK, params, tmp_path)
    assert record.exit_code == 1  # out of reach: not converged, never a silent claim
    pose = _pose(tmp_path)
    assert pose["plant_residual_m"]["com"] < 1e-4
    assert [level["tasks"] for level in pose["levels"]] == [
        ["left_foot", "right_foot", "right_palm", "pelvis", "com"], ["left_palm", "posture"]]
    assert pose["levels"][0]["residual"]["position [m]"] < 1e-4
    assert "priority levels (0 first" in record.summary()
    robot = with_palm_sites(g1)
    q0 = robot.keyframe_q("stand")
    heavy = QPWholeBodyIK(robot, g1_config(com_cost=1e4), q0)
    start = np.linalg.norm(heavy.frame_position("left_palm") - target)
    heavy.set_target_position("left_palm", target)
    heavy.set_com_target([0.0, 0.0])
    res = heavy.solve(q0, max_iters=80)
    palm = pose["plant_residual_m"]["left_palm"]
    assert palm < start - 0.1  # the palm moved well towards its target
    assert palm == pytest.approx(res.residuals["left_palm"].position_m, abs=0.02)
    assert res.residuals["com"].position_m > pose["plant_residual_m"]["com"]  # only approximately held
