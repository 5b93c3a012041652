"""2-link arm: analytic kinematics vs Pinocchio and MuJoCo, analytic and iterative IK."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mbctl.control import IKSetupError, UnreachableTarget
from mbctl.control.ik import ElbowBranch, TwoLinkArm, dls_ik, pinv_ik

angles = st.floats(-math.pi, math.pi, allow_nan=False)


@pytest.fixture(scope="module")
def arm(two_link) -> TwoLinkArm:
    return TwoLinkArm.from_robot(two_link)


def _pin_site(robot, q):
    data = robot.pin_model.createData()
    pin.computeJointJacobians(robot.pin_model, data, q)
    pin.updateFramePlacements(robot.pin_model, data)
    fid = robot.frame_id("end_effector")
    J = pin.getFrameJacobian(robot.pin_model, data, fid, pin.LOCAL_WORLD_ALIGNED)
    return data.oMf[fid].translation.copy(), J


def _mj_site(robot, q):
    m = robot.mj_model
    d = mujoco.MjData(m)
    d.qpos[:] = robot.converter.q_pin_to_mj(q)
    mujoco.mj_kinematics(m, d)
    mujoco.mj_comPos(m, d)
    sid = robot.site_id("end_effector")
    jacp = np.zeros((3, m.nv))
    mujoco.mj_jacSite(m, d, jacp, None, sid)
    return d.site_xpos[sid].copy(), jacp


def test_geometry_read_from_model(arm):
    assert arm.link1_length == pytest.approx(0.3, abs=1e-15)
    assert arm.link2_length == pytest.approx(0.315, abs=1e-15)
    ws = arm.workspace()
    assert ws.r_min == pytest.approx(0.015, abs=1e-15)
    assert ws.r_max == pytest.approx(0.615, abs=1e-15)


@settings(max_examples=60, deadline=None)
@given(q1=angles, q2=angles)
def test_fk_and_jacobian_match_pinocchio_and_mujoco(two_link, q1, q2):
    arm = TwoLinkArm.from_robot(two_link)
    q = np.array([q1, q2])
    p_pin, J_pin = _pin_site(two_link, q)
    p_mj, J_mj = _mj_site(two_link, q)
    p = arm.forward_kinematics(q)
    J = arm.jacobian(q)
    np.testing.assert_allclose(p, p_pin[:2], atol=1e-12, rtol=0)
    np.testing.assert_allclose(p, p_mj[:2], atol=1e-12, rtol=0)
    np.testing.assert_allclose(J, J_pin[:2, :], atol=1e-12, rtol=0)
    np.testing.assert_allclose(J, J_mj[:2, :], atol=1e-12, rtol=0)
    assert abs(p_pin[2]) < 1e-15 and np.all(np.abs(J_pin[2:, :][:1]) < 1e-15)


@settings(max_examples=30, deadline=None)
@given(q1=angles, q2=angles)
def test_jacobian_matches_finite_differences(arm, q1, q2):
    q = np.array([q1, q2])
    h = 1e-6
    J_fd = np.column_stack(
        [(arm.forward_kinematics(q + h * e) - arm.forward_kinematics(q - h * e)) / (2 * h)
         for e in np.eye(2)]
    )
    assert np.max(np.abs(arm.jacobian(q) - J_fd)) < 1e-9


@settings(max_examples=30, deadline=None)
@given(q1=angles, q2=angles)
def test_manipulability_is_abs_det_and_sqrt_det_jjt(arm, q1, q2):
    q = np.array([q1, q2])
    J = arm.jacobian(q)
    w = arm.manipulability(q)

    def det2(A):  # explicit 2x2 determinant (np.linalg.det warns on exactly singular input)
        return A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]

    assert w == pytest.approx(abs(det2(J)), abs=1e-13)
    assert w == pytest.approx(math.sqrt(max(det2(J @ J.T), 0.0)), abs=1e-7)


def test_singularity_detection(arm):
    assert arm.is_singular([0.3, 0.0])
    assert arm.is_singular([0.3, math.pi])
    assert arm.is_singular([0.3, 1e-8])
    assert not arm.is_singular([0.3, 0.5])
    assert arm.manipulability([0.0, 0.0]) == 0.0
    assert arm.manipulability([0.0, math.pi / 2]) == pytest.approx(0.3 * 0.315, rel=1e-15)


@settings(max_examples=60, deadline=None)
@given(q1=angles, q2=st.floats(0.01, math.pi - 0.01))
def test_analytic_ik_both_branches_round_trip(arm, q1, q2):
    p = arm.forward_kinematics([q1, q2])
    sols = arm.inverse_kinematics_both(p)
    assert sols[ElbowBranch.UP][1] <= 0.0 <= sols[ElbowBranch.DOWN][1]
    for q in sols.values():
        np.testing.assert_allclose(arm.forward_kinematics(q), p, atol=1e-12, rtol=0)
    # the DOWN branch recovers the sampled q (q2 > 0), angles wrapped
    d = sols[ElbowBranch.DOWN] - np.array([q1, q2])
    assert np.max(np.abs(np.arctan2(np.sin(d), np.cos(d)))) < 1e-7


def test_analytic_ik_elbow_up_is_above_line_for_target_on_x_axis(arm):
    q_up = arm.inverse_kinematics([0.4, 0.0], ElbowBranch.UP)
    q_down = arm.inverse_kinematics([0.4, 0.0], ElbowBranch.DOWN)
    assert arm.elbow_position(q_up)[1] > 0.0 > arm.elbow_position(q_down)[1]


def test_analytic_ik_on_boundary(arm):
    q = arm.inverse_kinematics([arm.r_max, 0.0])
    np.testing.assert_allclose(q, [0.0, 0.0], atol=1e-7)
    q = arm.inverse_kinematics([0.0, arm.r_min])
    np.testing.assert_allclose(arm.forward_kinematics(q), [0.0, arm.r_min], atol=1e-12)


@pytest.mark.parametrize("target", [[0.7, 0.0], [0.0, 0.01], [0.0, 0.0], [-0.5, 0.5]])
def test_unreachable_target_raises_with_annulus(arm, target):
    with pytest.raises(UnreachableTarget) as info:
        arm.inverse_kinematics(target)
    msg = str(info.value)
    assert "r_min=0.015 m" in msg and "r_max=0.615 m" in msg
    assert info.value.radius == pytest.approx(math.hypot(*target))


def test_bad_inputs_raise_setup_error(arm):
    with pytest.raises(IKSetupError, match="2 finite joint angles"):
        arm.forward_kinematics([0.0, float("nan")])
    with pytest.raises(IKSetupError, match="damping must be a positive"):
        dls_ik(arm, [0.3, 0.3], [0.1, 0.1], damping=0.0)


@pytest.mark.parametrize("solver", [pinv_ik, dls_ik])
def test_iterative_ik_converges(arm, solver):
    target = arm.forward_kinematics([0.7, -1.1])
    res = solver(arm, target, [0.1, 0.5], tol=1e-10)
    assert res.converged
    assert res.residuals["end_effector"].position_m < 1e-10
    assert len(res.position_history) == res.iterations + 1
    assert len(res.step_norms) == res.iterations
    assert res.position_history[0] > 0.1
    np.testing.assert_allclose(arm.forward_kinematics(res.q), target, atol=1e-10)
    assert res.iterations <= (10 if solver is pinv_ik else 200)


def test_dls_bounded_where_pinv_blows_up_near_stretched_singularity(arm):
    # Nearly stretched out (sin q2 = 1e-4); target pulled 15 mm inward along the arm.
    q0 = np.array([0.0, 1e-4])
    target = np.array([0.6, 0.0])
    e0 = float(np.linalg.norm(target - arm.forward_kinematics(q0)))
    lam = 0.05
    pinv = pinv_ik(arm, target, q0, max_iters=1)
    dls = dls_ik(arm, target, q0, damping=lam, max_iters=1, max_task_step=None)
    assert pinv.step_norms[0] > 100.0  # rad: ~1/sin(q2) blow-up
    assert dls.step_norms[0] <= e0 / (2 * lam) + 1e-12
    assert dls.step_norms[0] < 0.2
    # ... the same pseudo-inverse blow-up with the error clamp: the clamp does not fix it.
    assert pinv_ik(arm, target, q0, max_iters=1, max_task_step=0.05).step_norms[0] > 100.0
    # ... and DLS still gets there, every step within its bound.
    full = dls_ik(arm, target, q0, damping=lam, tol=1e-9, max_iters=500)
    assert full.converged
    bound = np.minimum(full.position_history[:-1], 0.05) / (2 * lam)  # steps' inf-norms within it
    assert np.all(full.step_norms <= bound + 1e-12)


def test_dls_unreachable_converges_to_closest_point(arm):
    target = np.array([1.0, 0.0])
    res = dls_ik(arm, target, [0.2, 0.4], damping=0.05, tol=1e-10, max_iters=300)
    assert not res.converged
    # DLS creeps toward the stretched-out singularity (steps shrink like sin q2): within 3 mm
    # of the closest distance after 300 steps, pointing at the target, never diverging.
    assert 0.0 <= res.residuals["end_effector"].position_m - (1.0 - arm.r_max) < 3e-3
    p = arm.forward_kinematics(res.q)
    assert abs(math.atan2(p[1], p[0])) < 1e-3
    assert res.position_history[-1] <= res.position_history[-50]
