"""Whole-body IK on the G1 task set: palm sites, our Pinocchio QP vs mink, convergence, limits."""

from __future__ import annotations

import json

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from mbctl.control.exceptions import IKSetupError
from mbctl.control.ik import MinkWholeBodyIK, QPWholeBodyIK, WholeBodyIKConfig
from mbctl.control.tasks import Tolerance
from mbctl.robots.g1 import FEET, PALM_OFFSET_IN_WRIST_YAW_M, PALM_SITES, PELVIS, with_palm_sites


def g1_whole_body_config(**weights):
    """The G1 task set of ``mbctl ik`` (mink's humanoid example), from the G1's names."""
    return WholeBodyIKConfig(held_frames=FEET, target_frames=tuple(PALM_SITES), base_frame=PELVIS, com=True,
                             **weights)


#: Agreement of the mink and Pinocchio velocity steps [rad/s, m/s] (inf-norm): both solve the
#: same strictly convex QP with daqp; the residual is round-off (measured ~1e-15).
STEP_ATOL = 1e-10


@pytest.fixture(scope="module")
def g1p(g1):
    return with_palm_sites(g1)


def _perturbed(robot, seed, scale=0.05):
    rng = np.random.default_rng(seed)
    return pin.integrate(robot.pin_model, robot.keyframe_q("stand"), scale * rng.standard_normal(
        robot.nv))


def test_palm_sites_added_in_both_engines(g1p, g1):
    assert "left_palm" not in g1.sites  # the fixture's model is untouched
    assert any("site left_palm on body left_wrist_yaw_link" in e for e in g1p.source.edits)
    assert with_palm_sites(g1p) is g1p  # idempotent
    q = _perturbed(g1p, 0, 0.3)
    data = mujoco.MjData(g1p.mj_model)
    data.qpos[:] = g1p.converter.q_pin_to_mj(q)
    mujoco.mj_kinematics(g1p.mj_model, data)
    pdata = g1p.pin_model.createData()
    pin.framesForwardKinematics(g1p.pin_model, pdata, q)
    for site, body in PALM_SITES.items():
        p_mj = data.site_xpos[g1p.site_id(site)]
        X_pin = pdata.oMf[g1p.frame_id(site)]
        np.testing.assert_allclose(X_pin.translation, p_mj, atol=1e-12, rtol=0)
        # the offset is where documented: in the wrist-yaw body frame
        X_body = pdata.oMf[g1p.pin_model.getFrameId(body, pin.FrameType.BODY)]
        np.testing.assert_allclose(X_body.actInv(X_pin).translation, PALM_OFFSET_IN_WRIST_YAW_M,
                                   atol=1e-12)


def _both(robot, q_ref, offset, com_xy=None):
    ours = QPWholeBodyIK(robot, g1_whole_body_config(), q_ref)
    theirs = MinkWholeBodyIK(robot, g1_whole_body_config(), q_ref)
    for palm in PALM_SITES:
        target = ours.frame_position(palm) + offset
        ours.set_target_position(palm, target)
        theirs.set_target_position(palm, target)
    if com_xy is not None:
        ours.set_com_target(com_xy)
        theirs.set_com_target(com_xy)
    return ours, theirs


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_mink_and_pinocchio_give_the_same_step(g1p, seed):
    q_ref = _perturbed(g1p, seed)
    ours, theirs = _both(g1p, q_ref, np.array([0.08, -0.03, 0.05]), com_xy=[0.01, -0.01])
    # Evaluate away from q_ref so that no task sits at exactly zero relative rotation (see below).
    q = _perturbed(g1p, seed + 100, 0.03)
    q[:7] = pin.integrate(g1p.pin_model, q, np.r_[0.02, -0.01, 0.03, 0.05, -0.04, 0.1,
                                                   np.zeros(g1p.nv - 6)])[:7]
    v_ours = ours.step(q)
    v_mink = theirs.step(q)
    assert np.max(np.abs(v_ours)) > 1e-2  # a real step, not a trivial zero
    assert np.max(np.abs(v_ours - v_mink)) < STEP_ATOL
    # mink's free-joint linear velocity is in the world frame: converted, not equal raw
    v_mink_raw = theirs.step_mj()
    assert np.max(np.abs(v_mink_raw[:3] - v_ours[:3])) > 1e-4


def test_pose_task_jacobian_at_zero_rotation(g1p):
    """At exactly zero relative rotation our SE3 Jacobian keeps the -[p]x/2 block of Jlog6 and
    matches finite differences. mink 1.3's jlog drops that block there (a mink bug, fixed
    upstream later); we rely only on mink's step still being a descent step for the palm, so
    this holds with either mink."""
    q = g1p.keyframe_q("stand")
    ours, theirs = _both(g1p, q, np.array([0.1, 0.0, 0.0]))
    task = ours.tasks["left_palm"]
    ours.update(q)
    J_ours = task.compute_jacobian(ours.state)
    h = 1e-6
    J_fd = np.column_stack([
        (task.compute_error(_at(ours, q, h * e)) - task.compute_error(_at(ours, q, -h * e)))
        / (2 * h) for e in np.eye(g1p.nv)
    ])
    assert np.max(np.abs(J_ours - J_fd)) < 1e-7
    before = theirs.task_residuals()["left_palm"].position_m
    theirs.update(q)
    theirs.configuration.integrate_inplace(theirs.step_mj(), theirs.config.dt)
    assert theirs.task_residuals()["left_palm"].position_m < 0.5 * before


def _at(ik, q, dq):
    ik.update(pin.integrate(ik.robot.pin_model, q, dq))
    return ik.state


@pytest.mark.parametrize("offset", [[0.1, 0.0, 0.0], [0.0, -0.1, 0.0]])
def test_palms_moved_10cm_converge_to_1mm_in_4_iterations(g1p, offset):
    q0 = g1p.keyframe_q("stand")
    ours = QPWholeBodyIK(g1p, g1_whole_body_config(), q0)
    for palm in PALM_SITES:
        ours.set_target_position(palm, ours.frame_position(palm) + offset)
    res = ours.solve(q0, Tolerance(1e-3), max_iters=10)
    assert res.converged
    assert res.iterations <= 4
    for palm in PALM_SITES:
        assert res.residuals[palm].position_m < 1e-3
    for foot in ("left_foot", "right_foot"):
        assert res.residuals[foot].position_m < 1e-3
    margins = ours.position_limit.margins(res.q)
    assert min(min(m) for m in margins.values()) >= -1e-9


def test_unreachable_palm_target_reports_residual(g1p):
    q0 = g1p.keyframe_q("stand")
    ours = QPWholeBodyIK(g1p, g1_whole_body_config(), q0)
    far = ours.frame_position("left_palm") + [1.5, 0.0, 0.0]
    ours.set_target_position("left_palm", far)
    res = ours.solve(q0, Tolerance(1e-3), max_iters=60)  # no exception: closest compromise pose
    assert not res.converged
    assert set(res.residuals) == set(ours.tasks)  # every task reports its residual
    assert res.residuals["left_palm"].position_m > 0.5
    # Feet are soft tasks (cost 10 vs palm 5): the 1.5 m pull drags them a few cm, no more.
    assert res.residuals["left_foot"].position_m < 5e-2
    assert res.residuals["right_palm"].position_m < 0.1
    margins = ours.position_limit.margins(res.q)
    assert min(min(m) for m in margins.values()) >= -1e-9


def test_palm_sites_required_and_config_validated(g1, g1p):
    with pytest.raises(IKSetupError, match="Unknown IK frame .*'left_palm'"):
        QPWholeBodyIK(g1, g1_whole_body_config(), g1.keyframe_q("stand"))
    ours = QPWholeBodyIK(g1p, g1_whole_body_config(), g1p.keyframe_q("stand"))
    with pytest.raises(IKSetupError, match="Unknown IK target frame 'left_foot'"):
        ours.set_target_position("left_foot", [0.0, 0.0, 0.0])
    with pytest.raises(IKSetupError, match="appear more than once"):
        WholeBodyIKConfig(held_frames=("a",), target_frames=("a",))
    with pytest.raises(IKSetupError, match="has no task"):
        WholeBodyIKConfig()
    with pytest.raises(IKSetupError, match="posture_cost must be >= 0; got -1"):
        WholeBodyIKConfig(com=True, posture_cost=-1)
    with pytest.raises(IKSetupError, match="dt must be > 0"):
        WholeBodyIKConfig(com=True, dt=0.0)


# ---------------------------------------------------------------------- CLI
def _mbctl(*args):
    import os
    import subprocess
    import sys

    return subprocess.run([sys.executable, "-m", "mbctl.cli", *args], capture_output=True,
                          text=True, timeout=300, env=dict(os.environ))


def test_cli_ik_g1_converges_and_writes_pose(g1, tmp_path):
    out = _mbctl("ik", "g1", "--target", "left_palm=0.1,0,0", "--target", "right_palm=0.1,0,0",
                 "--relative", "--com", "0,0", "--output", str(tmp_path), "--tol", "1e-3",
                 "--max-iters", "10", "--solver", "osqp")
    assert out.returncode == 0, out.stderr
    assert "result: converged" in out.stdout and "us/iteration" in out.stdout
    assert "left_palm" in out.stdout and "joint-limit margins" in out.stdout
    pose = json.loads((tmp_path / "ik_pose.json").read_text())
    assert pose["converged"] is True and pose["iterations"] <= 10
    assert pose["residuals"]["left_palm"]["position [m]"] < 1e-3
    assert set(pose["q"]) == set(g1.joints)
    assert len(pose["q"]["floating_base_joint"]) == 7
    assert pose["min_joint_limit_margin"] >= -1e-9


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--target", "left_plam=0.1,0.3,0.9"], "Did you mean 'left_palm'"),
        (["--target", "left_palm=0.1,0.3"], "must be 3 or 7 finite numbers as X,Y,Z or X,Y,Z,QW,QX,QY,QZ"),
        (["--target", "left_palm"], "--target must look like FRAME=X,Y,Z"),
        (["--target", "left_palm=0.1,0.3,0.9", "--com", "0.1"], "--com (m) must be 2 or 3 finite numbers"),
    ],
)
def test_cli_ik_bad_input_exits_2_with_message(g1, tmp_path, args, message):
    out = _mbctl("ik", "g1", *args, "--output", str(tmp_path))
    assert out.returncode == 2
    assert message in out.stderr
    assert "Traceback" not in out.stderr


@pytest.mark.parametrize(("angle_rad", "agree"), [(1e-7, False), (1e-6, False), (3e-6, False), (1e-3, True)])
def test_mink_jlog_drops_the_coupling_below_1e_5_rad(g1p, angle_rad, agree):
    """A palm target 10 cm ahead whose orientation is off by ``angle_rad``: ours (Pinocchio's
    exact Jlog6) matches finite differences at every angle; mink's ``SE3.jlog`` takes the
    identity when theta^2 < 1e-10 (theta < 1e-5 rad) and drops the translation-rotation block,
    so below that angle the first steps differ by percents; above it they agree (to 3e-8 at
    1e-3 rad, mink's small-angle series; to round-off at larger angles)."""
    q = g1p.keyframe_q("stand")
    ours, theirs = _both(g1p, q, np.array([0.1, 0.0, 0.0]))
    turn = pin.exp3(angle_rad * np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8]))
    for ik in (ours, theirs):
        for palm in PALM_SITES:  # both palms: a palm at exactly zero rotation would differ anyway
            target = ik.targets()[palm]
            ik.set_target_pose(palm, target.position, target.rotation @ turn)
    ours.update(q)
    task = ours.tasks["left_palm"]
    J_fd = np.column_stack([
        (task.compute_error(_at(ours, q, 1e-6 * e)) - task.compute_error(_at(ours, q, -1e-6 * e))) / 2e-6
        for e in np.eye(g1p.nv)])
    ours.update(q)
    assert np.max(np.abs(task.compute_jacobian(ours.state) - J_fd)) < 1e-7
    v_ours, v_mink = ours.step(q), theirs.step(q)
    relative = np.max(np.abs(v_ours - v_mink)) / np.max(np.abs(v_ours))
    if agree:
        assert relative < 1e-6
    else:
        assert relative > 0.01
