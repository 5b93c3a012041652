"""Cartesian paths, their jerk-limited timing law, and the conversion to joints on the 2-link arm."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mbctl.control.ik.two_link import ElbowBranch, TwoLinkArm
from mbctl.planners import (
    CartesianTrajectory,
    CirclePath,
    InvalidLimits,
    InvalidPath,
    InvalidPlanningInput,
    LinePath,
    PathIKFailed,
    PathLimits,
    PathNotTrackable,
    PolylinePath,
    square_path,
    time_path,
    to_joint_trajectory,
)

#: Relative slack on a limit [-]: round-off only.
LIMIT_RTOL = 1e-9
DT = 0.002


@pytest.fixture(scope="module")
def arm(two_link) -> TwoLinkArm:
    return TwoLinkArm.from_robot(two_link)


PATH_LIMITS = PathLimits(max_speed=0.25, max_acceleration=1.0, max_jerk=10.0)


def _check_path_limits(ct: CartesianTrajectory, limits: PathLimits) -> None:
    """|v| = s_dot on an arc-length path; s_ddot and jerk from differences of s_dot."""
    assert np.max(ct.speed) <= limits.max_speed * (1 + LIMIT_RTOL)
    # s is non-decreasing (the law never backs up) and its difference quotient is a mean speed.
    assert np.all(np.diff(ct.s) >= 0.0)
    assert np.max(np.diff(ct.s) / ct.dt_s) <= limits.max_speed * (1 + LIMIT_RTOL)


def test_square_corners_exact_and_at_rest():
    sq = square_path([0.35, 0.1, 0.0], side_length=0.2)
    np.testing.assert_allclose(sq.corners, [0.0, 0.2, 0.4, 0.6, 0.8], atol=1e-15)
    ct = time_path(sq, PATH_LIMITS, DT)
    expected = np.array([[0.25, 0.0, 0.0], [0.45, 0.0, 0.0], [0.45, 0.2, 0.0],
                         [0.25, 0.2, 0.0], [0.25, 0.0, 0.0]])
    idx = list(ct.corner_indices)
    assert len(idx) == 5 and idx[0] == 0 and idx[-1] == len(ct.t_s) - 1
    np.testing.assert_allclose(ct.p[idx], expected, atol=1e-15)
    np.testing.assert_array_equal(ct.v[idx], 0.0)
    np.testing.assert_array_equal(ct.a[idx], 0.0)
    _check_path_limits(ct, PATH_LIMITS)
    # Tangential acceleration and jerk of s (straight edges: |a| = |s_ddot|).
    assert np.max(np.linalg.norm(ct.a, axis=1)) <= PATH_LIMITS.max_acceleration * (1 + LIMIT_RTOL)
    s_acc = np.array([np.dot(a, t) for a, t in zip(ct.a, sq.tangent(ct.s), strict=True)])
    jerk = np.diff(s_acc) / DT
    assert np.max(np.abs(jerk)) <= PATH_LIMITS.max_jerk * (1 + LIMIT_RTOL)
    # Every edge is straight: each sample lies on the square's boundary.
    x, y = ct.p[:, 0], ct.p[:, 1]
    on_edge = np.minimum.reduce([np.abs(x - 0.25), np.abs(x - 0.45), np.abs(y), np.abs(y - 0.2)])
    assert np.max(on_edge) < 1e-15
    np.testing.assert_array_equal(ct.p[:, 2], 0.0)


def test_square_to_joint_trajectory_reproduces_path(arm, check_consistent):
    ct = time_path(square_path([0.35, 0.1, 0.0], 0.2), PATH_LIMITS, DT)
    jt = to_joint_trajectory(ct, arm.inverse_kinematics, arm.jacobian, ("shoulder", "elbow"))
    np.testing.assert_array_equal(jt.t_s, ct.t_s)
    fk = np.array([arm.forward_kinematics(q) for q in jt.q])
    assert np.max(np.abs(fk - ct.p[:, :2])) < 1e-9
    # Cartesian velocity reproduced exactly: J qd = v.
    jv = np.array([arm.jacobian(q) @ qd for q, qd in zip(jt.q, jt.v, strict=True)])
    assert np.max(np.abs(jv - ct.v[:, :2])) < 1e-12
    check_consistent(jt)
    np.testing.assert_array_equal(jt.v[list(ct.corner_indices)], 0.0)


def test_circle_joint_trajectory_accelerations(arm, check_consistent):
    circle = CirclePath([0.3, 0.05, 0.0], 0.1)
    assert circle.length == pytest.approx(2 * math.pi * 0.1)
    ct = time_path(circle, PATH_LIMITS, DT)
    np.testing.assert_allclose(ct.p[-1], ct.p[0], atol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(ct.p - circle.center, axis=1), 0.1, atol=1e-15)
    _check_path_limits(ct, PATH_LIMITS)
    # a = t s_ddot + k s_dot^2 with k normal to t: the tangential part is s_ddot.
    s_acc = np.einsum("ij,ij->i", ct.a, circle.tangent(ct.s))
    assert np.max(np.abs(s_acc)) <= PATH_LIMITS.max_acceleration * (1 + LIMIT_RTOL)
    assert np.max(np.abs(np.diff(s_acc)) / DT) <= PATH_LIMITS.max_jerk * (1 + LIMIT_RTOL)
    normal_acc = np.linalg.norm(ct.a - s_acc[:, None] * circle.tangent(ct.s), axis=1)
    np.testing.assert_allclose(normal_acc, ct.speed**2 / 0.1, rtol=1e-9, atol=1e-15)
    jt = to_joint_trajectory(ct, arm.inverse_kinematics, arm.jacobian, ("shoulder", "elbow"))
    fk = np.array([arm.forward_kinematics(q) for q in jt.q])
    assert np.max(np.abs(fk - ct.p[:, :2])) < 1e-9
    # J qdd + Jdot qd = a, with an analytic Jdot of the 2-link arm.
    l1, l2 = arm.link1_length, arm.link2_length

    def jdot(q, qd):
        s1, c1 = math.sin(q[0]), math.cos(q[0])
        s12, c12 = math.sin(q[0] + q[1]), math.cos(q[0] + q[1])
        w1, w12 = qd[0], qd[0] + qd[1]
        return np.array([[-l1 * c1 * w1 - l2 * c12 * w12, -l2 * c12 * w12],
                         [-l1 * s1 * w1 - l2 * s12 * w12, -l2 * s12 * w12]])

    jt_exact = to_joint_trajectory(ct, arm.inverse_kinematics, arm.jacobian,
                                   ("shoulder", "elbow"), jacobian_dot=jdot)
    # The finite-difference Jdot matches the analytic one closely.
    assert np.max(np.abs(jt.a - jt_exact.a)) < 1e-6
    recon = np.array([arm.jacobian(q) @ qdd + jdot(q, qd) @ qd
                      for q, qd, qdd in zip(jt_exact.q, jt_exact.v, jt_exact.a, strict=True)])
    assert np.max(np.abs(recon - ct.a[:, :2])) < 1e-10
    check_consistent(jt)


def test_line_path_and_3d_jacobian():
    line = LinePath([0.0, 0.0, 0.0], [0.3, 0.4, 0.0])
    assert line.length == pytest.approx(0.5)
    ct = time_path(line, PATH_LIMITS, DT)
    np.testing.assert_array_equal(ct.p[-1], [0.3, 0.4, 0.0])
    # A Cartesian "robot" with q = p: IK is the identity, J = I (3, 3).
    jt = to_joint_trajectory(ct, lambda p: p, lambda q: np.eye(3), ("x", "y", "z"))
    np.testing.assert_allclose(jt.q, ct.p, atol=0)
    np.testing.assert_allclose(jt.v, ct.v, atol=1e-15)
    np.testing.assert_allclose(jt.a, ct.a, atol=1e-15)


def test_unreachable_path_raises_with_time(arm):
    line = LinePath([0.3, 0.0, 0.0], [0.7, 0.0, 0.0])  # r_max = 0.615 m
    ct = time_path(line, PATH_LIMITS, DT)
    with pytest.raises(PathIKFailed, match=r"IK failed at t = [0-9.]+ s \(sample \d+\)") as info:
        to_joint_trajectory(ct, arm.inverse_kinematics, arm.jacobian, ("shoulder", "elbow"))
    err = info.value
    assert "UnreachableTarget" in str(err) and "r_max=0.615 m" in str(err)
    assert err.t_s == ct.t_s[err.sample_index]
    assert np.hypot(*err.position) > arm.r_max
    assert np.hypot(*ct.p[err.sample_index - 1, :2]) <= arm.r_max
    assert type(err.__cause__).__name__ == "UnreachableTarget"


@settings(max_examples=15, deadline=None)
@given(st.floats(0.1, 0.45), st.floats(-math.pi, math.pi), st.floats(0.02, 0.12),
       st.floats(-math.pi, math.pi))
def test_square_property_fk_reproduction(check_consistent, arm, radius, angle, side, edge_angle):
    center = np.array([radius * math.cos(angle), radius * math.sin(angle), 0.0])
    # Keep the whole square inside the annulus (with margin from the singular boundaries).
    half_diag = side / math.sqrt(2)
    if radius + half_diag > arm.r_max - 0.02 or radius - half_diag < arm.r_min + 0.05:
        return
    sq = square_path(center, side, edge_direction=(math.cos(edge_angle), math.sin(edge_angle), 0))
    ct = time_path(sq, PATH_LIMITS, 0.005)
    np.testing.assert_array_equal(ct.v[list(ct.corner_indices)], 0.0)
    jt = to_joint_trajectory(ct, arm.inverse_kinematics, arm.jacobian, ("shoulder", "elbow"),
                             unwrap=True)
    fk = np.array([arm.forward_kinematics(q) for q in jt.q])
    assert np.max(np.abs(fk - ct.p[:, :2])) < 1e-9
    check_consistent(jt)


def test_square_across_the_angle_wrap_needs_unwrap(arm, check_consistent):
    # Centred where the UP-branch shoulder angle is pi: it crosses +-pi, where the IK wraps.
    center = np.append(arm.forward_kinematics([math.pi, -1.0]), 0.0)
    ct = time_path(square_path(center, 0.05), PATH_LIMITS, 0.005)
    with pytest.raises(InvalidPlanningInput, match="ik jumped 6.28 rad on joint 'shoulder'"):
        to_joint_trajectory(ct, arm.inverse_kinematics, arm.jacobian, ("shoulder", "elbow"))
    jt = to_joint_trajectory(ct, arm.inverse_kinematics, arm.jacobian, ("shoulder", "elbow"),
                             unwrap=True)
    assert np.max(np.abs(jt.q[:, 0])) > math.pi  # continued past +-pi instead of jumping
    fk = np.array([arm.forward_kinematics(q) for q in jt.q])
    assert np.max(np.abs(fk - ct.p[:, :2])) < 1e-9
    check_consistent(jt)


def test_singular_jacobian_is_not_trackable():
    ct = time_path(LinePath([0.0, 0.0, 0.0], [0.0, 0.1, 0.0]), PATH_LIMITS, DT)
    # A "robot" that can only move along x: J has rank 1 and v_y is lost by the pseudo-inverse.
    with pytest.raises(PathNotTrackable, match=r"cannot produce the Cartesian velocity") as info:
        to_joint_trajectory(ct, lambda p: np.array([p[0], 0.0]),
                            lambda q: np.array([[1.0, 0.0], [0.0, 0.0]]), ("a", "b"))
    assert info.value.sample_index == 1 and info.value.residual > 0.0


def test_ik_branch_jump_and_off_plane_motion_rejected(arm):
    ct = time_path(LinePath([0.3, 0.0, 0.0], [0.3, 0.2, 0.0]), PATH_LIMITS, DT)

    def flipping_ik(p):
        branch = ElbowBranch.UP if p[1] < 0.1 else ElbowBranch.DOWN
        return arm.inverse_kinematics(p, branch)

    with pytest.raises(InvalidPlanningInput, match="the IK switched branch"):
        to_joint_trajectory(ct, flipping_ik, arm.jacobian, ("shoulder", "elbow"))
    tilted = time_path(LinePath([0.3, 0.0, 0.0], [0.3, 0.1, 0.05]), PATH_LIMITS, DT)
    with pytest.raises(InvalidPath, match="along z, which the 2-row Jacobian ignores"):
        to_joint_trajectory(tilted, arm.inverse_kinematics, arm.jacobian, ("shoulder", "elbow"))


def test_path_bad_inputs():
    with pytest.raises(InvalidPath, match="radius = 0.0 m must be finite and > 0"):
        CirclePath([0, 0, 0], 0.0)
    with pytest.raises(InvalidPath, match="is parallel to the normal"):
        CirclePath([0, 0, 0], 0.1, normal=(1, 0, 0), start_direction=(2, 0, 0))
    with pytest.raises(InvalidPath, match="side_length = -1.0 m must be finite and > 0"):
        square_path([0, 0, 0], -1.0)
    with pytest.raises(InvalidPath, match="segment 1 from vertex 1 to 2 has length 0.0 m"):
        PolylinePath([[0, 0, 0], [1, 0, 0], [1, 0, 0]])
    with pytest.raises(InvalidPath, match=r"path parameter s = 2.0 m is outside"):
        LinePath([0, 0, 0], [1, 0, 0]).position(2.0)
    with pytest.raises(InvalidLimits, match="max_speed = -1.0 m/s must be finite and > 0"):
        PathLimits(-1.0, 1.0, 1.0)
