"""Chain IK (damped least squares on one limb): the G1's leg under its foot, the 2-link arm, the errors."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from mbctl.control.exceptions import IKSetupError
from mbctl.control.ik import ChainIK, TwoLinkArm, chain_joints
from mbctl.control.tasks import FramePoseTask, FramePositionTask, Tolerance
from mbctl.robots.g1 import FEET, PELVIS, crouched_start

TOLERANCE = Tolerance(position_m=1e-6, orientation_rad=1e-6)


def _foot_pose(model, q, frame):
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    return pin.SE3(data.oMf[model.getFrameId(frame)])


def _newton(model, q, foot, X_WT, idx_q, idx_v, iterations=20):
    """Undamped Newton on log6(X_FT) with the foot's body Jacobian (the reference solution)."""
    q, data, fid = q.copy(), model.createData(), model.getFrameId(foot)
    for _ in range(iterations):
        pin.framesForwardKinematics(model, data, q)
        J = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL)[:, idx_v]
        q[idx_q] += np.linalg.solve(J, pin.log6(data.oMf[fid].actInv(X_WT)).vector)
    return q


@pytest.fixture(scope="module")
def leg(g1):
    """The G1's right leg under a pose task on its foot, from the crouched start."""
    model = g1.pin_model
    task = FramePoseTask(FEET[1], model, lm_damping=1.0)
    return ChainIK(model, [task], chain_joints(model, FEET[1]), damping=1e-6), task, crouched_start(g1)


def test_the_chain_of_a_foot_is_its_leg(g1):
    assert chain_joints(g1.pin_model, FEET[0]) == tuple(
        f"left_{j}_joint" for j in ("hip_pitch", "hip_roll", "hip_yaw", "knee", "ankle_pitch", "ankle_roll"))


def test_a_reachable_foot_pose_converges_moving_only_the_leg(leg):
    ik, task, q0 = leg
    X0 = _foot_pose(ik.model, q0, FEET[1])
    X_WT = pin.SE3(pin.rpy.rpyToMatrix(0.05, -0.1, 0.02) @ X0.rotation, X0.translation + [0.03, -0.01, 0.05])
    task.set_target(X_WT)
    res = ik.solve(q0, TOLERANCE, max_iters=20)
    assert res.converged and not res.stalled and res.iterations <= 6
    off_chain = np.setdiff1d(np.arange(ik.model.nq), ik.idx_q)
    np.testing.assert_array_equal(res.q[off_chain], q0[off_chain])  # base and other limbs held exactly
    assert (pin.log6(_foot_pose(ik.model, res.q, FEET[1]).actInv(X_WT)).vector ** 2).sum() ** 0.5 < 2e-6
    # the same solution as undamped Newton (unique near the start for 6 joints under a 6-dof pose)
    np.testing.assert_allclose(res.q, _newton(ik.model, q0, FEET[1], X_WT, ik.idx_q, ik.idx_v), atol=1e-6)


def test_an_unreachable_foot_pose_is_reported_and_stays_inside_the_limits(leg):
    ik, task, q0 = leg
    X0 = _foot_pose(ik.model, q0, FEET[1])
    task.set_target(pin.SE3(X0.rotation, X0.translation + [0.0, 0.0, 0.6]))  # foot at the hip's height
    res = ik.solve(q0, TOLERANCE, max_iters=30)
    assert not res.converged and res.residuals[task.name].position_m > 0.05
    lo, hi = ik.model.lowerPositionLimit[ik.idx_q], ik.model.upperPositionLimit[ik.idx_q]
    assert np.all(np.isfinite(res.q)) and np.all(res.q[ik.idx_q] >= lo) and np.all(res.q[ik.idx_q] <= hi)


def test_the_2link_arm_reaches_the_analytic_solution(two_link):
    """A fixed base: the chain is the whole arm; from near the elbow-down branch it lands on it."""
    arm = TwoLinkArm.from_robot(two_link)
    model = two_link.pin_model
    q_true = np.array([0.4, 0.9])
    task = FramePositionTask("end_effector", model)
    task.set_target(_foot_pose(model, q_true, "end_effector").translation)
    ik = ChainIK(model, [task], chain_joints(model, "end_effector"))
    assert ik.joints == tuple(model.names[1:])
    res = ik.solve(np.array([0.3, 0.7]), Tolerance(position_m=1e-9))
    assert res.converged
    np.testing.assert_allclose(res.q, q_true, atol=1e-8)
    np.testing.assert_allclose(arm.forward_kinematics(res.q), arm.forward_kinematics(q_true), atol=1e-9)


def test_setup_errors_name_the_problem(g1):
    model = g1.pin_model
    task = FramePoseTask(FEET[0], model)
    with pytest.raises(IKSetupError, match="is on the base"):
        chain_joints(model, PELVIS)
    with pytest.raises(IKSetupError, match="Unknown frame 'left_fot'"):
        chain_joints(model, "left_fot")
    with pytest.raises(IKSetupError, match="damping must be > 0"):
        ChainIK(model, [task], ["left_knee_joint"], damping=0.0)
    with pytest.raises(IKSetupError, match="distinct joint names"):
        ChainIK(model, [task], ["left_knee_joint", "left_knee_joint"])
    with pytest.raises(IKSetupError, match="Unknown joint 'left_kne_joint'"):
        ChainIK(model, [task], ["left_kne_joint"])
    with pytest.raises(IKSetupError, match="at least one task"):
        ChainIK(model, [], ["left_knee_joint"])
