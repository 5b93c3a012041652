"""Planners: ruckig state-to-state and waypoints, polynomials, Cartesian paths and joint conversion.

Limit checks use the sampled v and a from ruckig (exact samples of the profile) and the jerk
from a forward difference of a: ruckig's acceleration is piecewise linear, so the difference
quotient over one period is a mean of the jerk and stays within the bound up to round-off.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from ruckig import (
    DurationDiscretization,
    InputParameter,
    Result,
    Ruckig,
    Synchronization,
    Trajectory,
)

from mbctl.control.ik.two_link import ElbowBranch, TwoLinkArm
from mbctl.planners import (
    CartesianTrajectory,
    CirclePath,
    InvalidLimits,
    InvalidPath,
    InvalidPlanningInput,
    JointLimits,
    JointTrajectory,
    LinePath,
    PathIKFailed,
    PathLimits,
    PathNotTrackable,
    PlanningError,
    PolylinePath,
    TrajectoryGenerationFailed,
    cubic_trajectory,
    minimum_jerk_trajectory,
    pass_through_velocities,
    plan_ruckig,
    plan_waypoints,
    quintic_trajectory,
    square_path,
    time_path,
    to_joint_trajectory,
)

#: Relative slack on a limit [-]: round-off only (sampled values are exact profile values).
LIMIT_RTOL = 1e-9
DT = 0.002
NAMES3 = ("j1", "j2", "j3")
LIMITS3 = JointLimits([1.0, 0.8, 1.5], [2.0, 3.0, 1.0], [10.0, 20.0, 8.0])


def _check_limits(traj: JointTrajectory, limits: JointLimits) -> dict[str, float]:
    """Max |v|, |a|, |jerk| over the limits (ratios); asserts each <= 1 + LIMIT_RTOL."""
    jerk = np.diff(traj.a, axis=0) / traj.dt_s if len(traj.t_s) > 1 else np.zeros((1, 1))
    ratios = {
        "v": float(np.max(np.abs(traj.v) / limits.max_velocity)),
        "a": float(np.max(np.abs(traj.a) / limits.max_acceleration)),
        "j": float(np.max(np.abs(jerk) / limits.max_jerk)),
    }
    for key, ratio in ratios.items():
        assert ratio <= 1.0 + LIMIT_RTOL, (key, ratio)
    return ratios


def _check_consistent(traj: JointTrajectory) -> float:
    """q and v agree by central differences; returns the max error [rad/s].

    The central difference errs by ``dt^2 / 6 |jerk|``; the jerk is estimated from differences
    of a, with 50 % slack plus round-off.
    """
    dt = traj.dt_s
    v_fd = (traj.q[2:] - traj.q[:-2]) / (2 * dt)
    err = float(np.max(np.abs(v_fd - traj.v[1:-1])))
    jerk = float(np.max(np.abs(np.diff(traj.a, axis=0)))) / dt
    assert err <= 1.5 * dt**2 / 6 * jerk + 1e-9 * max(1.0, float(np.max(np.abs(traj.v))))
    return err


def _ruckig_alone(q0, q1, limits: JointLimits, dt: float) -> float:
    """Duration [s] ruckig itself finds for a rest-to-rest move (time-synchronized, discrete
    durations), without the planner; NaN where ruckig returns an error."""
    n = len(q0)
    inp = InputParameter(n)
    inp.current_position, inp.target_position = list(q0), list(q1)
    inp.current_velocity = inp.current_acceleration = [0.0] * n
    inp.target_velocity = inp.target_acceleration = [0.0] * n
    inp.max_velocity = limits.max_velocity.tolist()
    inp.max_acceleration = limits.max_acceleration.tolist()
    inp.max_jerk = limits.max_jerk.tolist()
    inp.synchronization = Synchronization.Time
    inp.duration_discretization = DurationDiscretization.Discrete
    out = Trajectory(n)
    result = Ruckig(n, dt).calculate(inp, out)
    return float(out.duration) if result in (Result.Working, Result.Finished) else math.nan


# ------------------------------------------------------------------------------ ruckig
def test_ruckig_reaches_target_exactly_within_limits_and_synchronized():
    q0, q1 = np.array([0.0, 0.5, -1.0]), np.array([1.2, -0.3, 0.4])
    traj = plan_ruckig(q0, q1, LIMITS3, DT, NAMES3)
    assert traj.names == NAMES3
    np.testing.assert_array_equal(traj.q[0], q0)
    np.testing.assert_array_equal(traj.q[-1], q1)
    np.testing.assert_array_equal(traj.v[[0, -1]], 0.0)
    np.testing.assert_array_equal(traj.a[[0, -1]], 0.0)
    # Uniform grid ending at ruckig's own time-optimal duration, a whole number of periods
    # (not the planner's rounding of its own duration, which would be equal by construction).
    np.testing.assert_allclose(np.diff(traj.t_s), DT, rtol=1e-9)
    expected_s = _ruckig_alone(q0, q1, LIMITS3, DT)
    assert expected_s == pytest.approx(1248 * DT, abs=1e-12)
    assert traj.duration_s == pytest.approx(expected_s, abs=1e-12) and len(traj.t_s) == 1249
    ratios = _check_limits(traj, LIMITS3)
    assert max(ratios.values()) > 0.9  # the limiting DoF actually uses its limits
    _check_consistent(traj)
    # Time synchronization: every DoF is still moving until the common end (none arrives early).
    for i in range(3):
        moving = np.flatnonzero(np.abs(traj.v[:, i]) > 1e-9)
        assert traj.t_s[moving[-1]] > traj.duration_s - 2 * DT


def test_ruckig_duration_is_the_slowest_single_dof_duration():
    q0, q1 = np.array([0.0, 0.5, -1.0]), np.array([1.2, -0.3, 0.4])
    traj = plan_ruckig(q0, q1, LIMITS3, DT, NAMES3)
    singles = [
        plan_ruckig(q0[[i]], q1[[i]], JointLimits(LIMITS3.max_velocity[[i]],
                                                  LIMITS3.max_acceleration[[i]],
                                                  LIMITS3.max_jerk[[i]]), DT, (NAMES3[i],))
        for i in range(3)
    ]
    durations = [s.duration_s for s in singles]
    assert traj.duration_s == pytest.approx(max(durations), abs=1e-12)
    assert min(durations) < traj.duration_s - 0.1  # some DoF was slowed down to synchronize


def test_ruckig_profile_boundary_input_is_retried():
    # Ruckig 0.19 alone raises for this input (a jerk-only profile exactly reaching max_accel,
    # one ulp long); the planner retries with limits tightened by 1e-9 relative.
    # The minimum-time profile is jerk +j, -j, +j for T, 2T, T with T = a_max / j = 0.1 s: it
    # covers 2 j T^3 = 0.02 rad in 4T = 0.4 s. One ulp more, and the tightened limits, make it
    # a hair longer than 80 periods, so the sampled trajectory takes 81.
    limits = JointLimits([0.25], [1.0], [10.0])
    traj = plan_ruckig([0.0], [0.02000000000000002], limits, 0.005, ("s",))
    assert traj.duration_s == pytest.approx(81 * 0.005, abs=1e-12)
    # the sampled velocity integrates to the displacement (the last sample is pinned to the
    # target by construction, so it cannot show this); trapezoid error ~2e-8 rad
    assert float(np.trapezoid(traj.v[:, 0], traj.t_s)) == pytest.approx(0.02, abs=1e-7)
    assert 0.09 < np.max(traj.v) <= 10.0 * 0.1**2 * (1 + LIMIT_RTOL)  # peak <= j T^2 = 0.1 rad/s
    _check_consistent(traj)
    _check_limits(traj, limits)


def test_ruckig_chains_with_joint_trajectory_then():
    first = plan_ruckig([0, 0, 0], [0.3, 0.2, 0.1], LIMITS3, DT, NAMES3)
    second = plan_ruckig([0.3, 0.2, 0.1], [0, 0, 0], LIMITS3, DT, NAMES3)
    both = first.then(second)
    assert len(both.t_s) == len(first.t_s) + len(second.t_s) - 1
    np.testing.assert_allclose(np.diff(both.t_s), DT, rtol=1e-9)
    np.testing.assert_array_equal(both.q[-1], 0.0)


def test_ruckig_with_initial_and_target_velocity():
    traj = plan_ruckig([0.0, 0.0, 0.0], [0.5, 0.5, -0.5], LIMITS3, DT, NAMES3,
                       current_velocity=[0.5, -0.4, 0.0], target_velocity=[0.2, 0.0, -0.1])
    np.testing.assert_array_equal(traj.v[0], [0.5, -0.4, 0.0])
    np.testing.assert_array_equal(traj.v[-1], [0.2, 0.0, -0.1])
    np.testing.assert_array_equal(traj.q[-1], [0.5, 0.5, -0.5])
    _check_limits(traj, LIMITS3)


def test_ruckig_minimum_duration_and_zero_motion():
    traj = plan_ruckig([0.1, 0.2, 0.3], [0.1, 0.2, 0.3], LIMITS3, DT, NAMES3)
    assert traj.duration_s == 0.0 and len(traj.t_s) == 1
    slow = plan_ruckig([0, 0, 0], [0.1, 0, 0], LIMITS3, DT, NAMES3, minimum_duration_s=3.0)
    assert slow.duration_s == pytest.approx(3.0, abs=1e-9)


limited = st.floats(-2.0, 2.0, allow_nan=False)


unit = st.floats(-1.0, 1.0, allow_nan=False)


@settings(max_examples=40, deadline=None)
@given(st.lists(limited, min_size=6, max_size=6), st.lists(unit, min_size=6, max_size=6),
       st.lists(st.floats(0.2, 3.0), min_size=3, max_size=3),
       st.lists(st.floats(0.5, 10.0), min_size=3, max_size=3),
       st.lists(st.floats(2.0, 100.0), min_size=3, max_size=3))
def test_ruckig_property_random_states_and_limits(positions, velocity_fractions, v_max, a_max,
                                                  j_max):
    limits = JointLimits(v_max, a_max, j_max)
    q0, q1 = np.array(positions[:3]), np.array(positions[3:])
    v0 = np.array(velocity_fractions[:3]) * limits.max_velocity
    v1 = np.array(velocity_fractions[3:]) * limits.max_velocity
    traj = plan_ruckig(q0, q1, limits, 0.005, NAMES3, current_velocity=v0, target_velocity=v1)
    np.testing.assert_array_equal(traj.q[-1], q1)
    np.testing.assert_array_equal(traj.v[-1], v1)
    # A single sample (start == target to round-off, e.g. v1 = 5e-39) holds the target state.
    if len(traj.t_s) > 1:
        np.testing.assert_array_equal(traj.q[0], q0)
        np.testing.assert_array_equal(traj.v[0], v0)
    _check_limits(traj, limits)


def test_waypoints_pass_through_every_waypoint_and_stop():
    wps = np.array([[0.0, 0.0, 0.0], [0.5, -0.2, 0.1], [0.5, 0.4, -0.3], [-0.1, 0.0, 0.0]])
    traj = plan_waypoints(wps, LIMITS3, DT, NAMES3)
    np.testing.assert_allclose(np.diff(traj.t_s), DT, rtol=1e-9)
    hits = [int(np.flatnonzero(np.all(traj.q == w, axis=1))[0]) for w in wps]
    assert hits == sorted(hits) and hits[0] == 0 and hits[-1] == len(traj.t_s) - 1
    np.testing.assert_array_equal(traj.v[hits], 0.0)
    _check_limits(traj, LIMITS3)
    _check_consistent(traj)


def test_waypoints_pass_through_with_velocities():
    wps = np.array([[0.0, 0.0, 0.0], [0.5, 0.3, 0.2], [1.0, 0.6, 0.4]])
    vels = np.array([[0.0, 0.0, 0.0], [0.5, 0.3, 0.2], [0.0, 0.0, 0.0]])
    traj = plan_waypoints(wps, LIMITS3, DT, NAMES3, waypoint_velocities=vels)
    k = int(np.flatnonzero(np.all(traj.q == wps[1], axis=1))[0])
    np.testing.assert_array_equal(traj.v[k], vels[1])
    _check_limits(traj, LIMITS3)
    stop = plan_waypoints(wps, LIMITS3, DT, NAMES3)
    assert traj.duration_s < stop.duration_s


def test_waypoints_pass_through_heuristic():
    wps = np.array([[0.0, 0.0, 0.0], [0.4, 0.3, 0.2], [0.8, 0.1, 0.5], [1.2, 0.5, 0.6]])
    vels = pass_through_velocities(wps, LIMITS3, DT, NAMES3)
    np.testing.assert_array_equal(vels[[0, -1]], 0.0)
    assert vels[1, 0] > 0 and vels[2, 0] > 0  # joint 1 keeps moving forward
    assert vels[1, 1] == 0.0 and vels[2, 1] == 0.0  # joint 2 reverses at both: stops there
    assert np.all(np.abs(vels) <= LIMITS3.max_velocity)
    traj = plan_waypoints(wps, LIMITS3, DT, NAMES3, waypoint_velocities=vels)
    hits = [int(np.flatnonzero(np.all(traj.q == w, axis=1))[0]) for w in wps]
    assert hits == sorted(hits)
    np.testing.assert_array_equal(traj.v[hits], vels)
    _check_limits(traj, LIMITS3)
    _check_consistent(traj)
    # Joint 1 never backs up between its waypoints (no overshoot on a monotone joint).
    assert np.all(traj.v[:, 0] >= -1e-12)
    assert traj.duration_s < plan_waypoints(wps, LIMITS3, DT, NAMES3).duration_s


def test_joint_limits_are_frozen_and_validated():
    limits = JointLimits.uniform(2, 1.0, 2.0, 3.0)
    assert limits.dofs == 2
    with pytest.raises(ValueError):
        limits.max_velocity[0] = 5.0
    with pytest.raises(InvalidLimits, match=r"max_acceleration\[1\] = -2.0 rad/s\^2 \(DoF 1\)"):
        JointLimits([1.0, 1.0], [2.0, -2.0], [3.0, 3.0])
    with pytest.raises(InvalidLimits, match=r"max_jerk\[0\] = inf rad/s\^3 \(DoF 0\)"):
        JointLimits([1.0], [2.0], [math.inf])
    with pytest.raises(InvalidLimits, match=r"max_velocity\[0\] = 0.0 rad/s"):
        JointLimits([0.0], [2.0], [3.0])
    with pytest.raises(InvalidLimits, match="max_jerk has 1 entries but max_velocity has 2"):
        JointLimits([1.0, 1.0], [2.0, 2.0], [3.0])
    with pytest.raises(InvalidLimits, match="limits cover 2 DoFs but the trajectory has 3"):
        plan_ruckig([0, 0, 0], [1, 1, 1], limits, DT, NAMES3)


def test_ruckig_bad_inputs():
    with pytest.raises(InvalidPlanningInput, match=r"target_position must have shape \(3,\)"):
        plan_ruckig([0, 0, 0], [1, 1], LIMITS3, DT, NAMES3)
    with pytest.raises(InvalidPlanningInput, match=r"current_position\[1\] = nan \(DoF 1\)"):
        plan_ruckig([0, math.nan, 0], [1, 1, 1], LIMITS3, DT, NAMES3)
    with pytest.raises(InvalidPlanningInput, match="dt_s must be finite and > 0"):
        plan_ruckig([0, 0, 0], [1, 1, 1], LIMITS3, 0.0, NAMES3)
    with pytest.raises(InvalidPlanningInput, match="names must be unique"):
        plan_ruckig([0, 0, 0], [1, 1, 1], LIMITS3, DT, ("a", "a", "b"))
    with pytest.raises(TrajectoryGenerationFailed,
                       match=r"target_velocity\[0\] = 5.0 rad/s \(DoF 0, 'j1'\) exceeds the limit"
                       r" 1.0 rad/s") as info:
        plan_ruckig([0, 0, 0], [1, 1, 1], LIMITS3, DT, NAMES3, target_velocity=[5.0, 0, 0])
    assert info.value.result == "ErrorInvalidInput"
    assert isinstance(info.value, PlanningError)
    # An input ruckig itself rejects (no profile for an astronomically long move).
    with pytest.raises(TrajectoryGenerationFailed, match="ruckig found no trajectory") as info:
        plan_ruckig([0, 0, 0], [1e12, 0, 0], LIMITS3, DT, NAMES3)
    assert info.value.result == "RuckigError"
    with pytest.raises(TrajectoryGenerationFailed,
                       match=r"segment 0 \(waypoint 0 -> 1\): target_velocity\[1\] = 2.0 rad/s"):
        plan_waypoints([[0, 0, 0], [1, 1, 1], [0, 0, 0]], LIMITS3, DT, NAMES3,
                       waypoint_velocities=[[0, 0, 0], [0, 2.0, 0], [0, 0, 0]])
    with pytest.raises(InvalidPlanningInput, match=r"waypoints needs at least 2 rows"):
        plan_waypoints([[0, 0, 0]], LIMITS3, DT, NAMES3)
    with pytest.raises(InvalidPlanningInput, match=r"waypoints must have shape \(K, 3\)"):
        plan_waypoints([[0, 0], [1, 1]], LIMITS3, DT, NAMES3)


# ------------------------------------------------------------------------------ polynomials
finite = st.floats(-3.0, 3.0, allow_nan=False, allow_subnormal=False)
vec2 = st.lists(finite, min_size=2, max_size=2)


@settings(max_examples=40, deadline=None)
@given(vec2, vec2, vec2, vec2, vec2, vec2, st.floats(0.2, 3.0))
def test_quintic_boundary_conditions_exact(q0, q1, v0, v1, a0, a1, duration):
    traj = quintic_trajectory(q0, q1, duration, 0.01, ("a", "b"), v0, v1, a0, a1)
    for got, want in ((traj.q[0], q0), (traj.v[0], v0), (traj.a[0], a0),
                      (traj.q[-1], q1), (traj.v[-1], v1), (traj.a[-1], a1)):
        np.testing.assert_array_equal(got, want)
    assert traj.duration_s >= duration - 1e-9 and traj.duration_s < duration + 0.01
    _check_consistent(traj)
    # Accelerations agree with central differences of v (error dt^2 / 6 |snap|).
    dt = traj.dt_s
    a_fd = (traj.v[2:] - traj.v[:-2]) / (2 * dt)
    snap = float(np.max(np.abs(np.diff(traj.a, 2, axis=0)))) / dt**2
    bound = 1.5 * dt**2 / 6 * snap + 1e-9 * max(1.0, float(np.max(np.abs(traj.a))))
    assert np.max(np.abs(a_fd - traj.a[1:-1])) <= bound


@settings(max_examples=30, deadline=None)
@given(vec2, vec2, vec2, vec2, st.floats(0.2, 3.0))
def test_cubic_boundary_conditions_exact(q0, q1, v0, v1, duration):
    traj = cubic_trajectory(q0, q1, duration, 0.01, ("a", "b"), v0, v1)
    for got, want in ((traj.q[0], q0), (traj.v[0], v0), (traj.q[-1], q1), (traj.v[-1], v1)):
        np.testing.assert_array_equal(got, want)
    # A cubic has constant jerk: second differences of a vanish.
    assert np.max(np.abs(np.diff(traj.a, 2, axis=0))) < 1e-9 * max(1.0, np.max(np.abs(traj.a)))
    _check_consistent(traj)


def test_minimum_jerk_shape_and_symmetry():
    q0, q1, T = np.array([0.2, -1.0]), np.array([1.2, 0.5]), 2.0
    traj = minimum_jerk_trajectory(q0, q1, T, 0.01, ("a", "b"))
    assert len(traj.t_s) == 201 and traj.duration_s == pytest.approx(T, abs=1e-12)
    tau = traj.t_s / T
    expected = q0 + np.outer(10 * tau**3 - 15 * tau**4 + 6 * tau**5, q1 - q0)
    np.testing.assert_allclose(traj.q, expected, atol=1e-14)
    # Point symmetry about the midpoint: q(t) + q(T - t) = q0 + q1, v even, a odd.
    np.testing.assert_allclose(traj.q + traj.q[::-1], np.broadcast_to(q0 + q1, traj.q.shape),
                               atol=1e-14)
    np.testing.assert_allclose(traj.v, traj.v[::-1], atol=1e-13)
    np.testing.assert_allclose(traj.a, -traj.a[::-1], atol=1e-12)
    np.testing.assert_allclose(traj.v[100], 1.875 * (q1 - q0) / T, rtol=1e-12)
    np.testing.assert_array_equal(traj.v[[0, -1]], 0.0)
    np.testing.assert_array_equal(traj.a[[0, -1]], 0.0)
    # Squared-jerk integral: 720 dq^2 / T^5 for the minimum-jerk profile (midpoint sum).
    jerk_cost = np.sum((np.diff(traj.a, axis=0) / 0.01) ** 2, axis=0) * 0.01
    np.testing.assert_allclose(jerk_cost, 720 * (q1 - q0) ** 2 / T**5, rtol=1e-3)


def test_polynomial_duration_rounding_and_bad_inputs():
    traj = minimum_jerk_trajectory([0.0], [1.0], 0.333, 0.01, ("a",))
    assert len(traj.t_s) == 35 and traj.duration_s == pytest.approx(0.34)
    with pytest.raises(InvalidPlanningInput, match=r"duration_s must be finite and > 0 \[s\]"):
        minimum_jerk_trajectory([0.0], [1.0], 0.0, 0.01, ("a",))
    with pytest.raises(InvalidPlanningInput, match=r"target_velocity must have shape \(1,\)"):
        cubic_trajectory([0.0], [1.0], 1.0, 0.01, ("a",), target_velocity=[1.0, 2.0])
    with pytest.raises(InvalidPlanningInput, match="dt_s must be finite and > 0"):
        quintic_trajectory([0.0], [1.0], 1.0, -0.01, ("a",))


# ------------------------------------------------------------------------------ Cartesian
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


def test_square_to_joint_trajectory_reproduces_path(arm):
    ct = time_path(square_path([0.35, 0.1, 0.0], 0.2), PATH_LIMITS, DT)
    jt = to_joint_trajectory(ct, arm.inverse_kinematics, arm.jacobian, ("shoulder", "elbow"))
    np.testing.assert_array_equal(jt.t_s, ct.t_s)
    fk = np.array([arm.forward_kinematics(q) for q in jt.q])
    assert np.max(np.abs(fk - ct.p[:, :2])) < 1e-9
    # Cartesian velocity reproduced exactly: J qd = v.
    jv = np.array([arm.jacobian(q) @ qd for q, qd in zip(jt.q, jt.v, strict=True)])
    assert np.max(np.abs(jv - ct.v[:, :2])) < 1e-12
    _check_consistent(jt)
    np.testing.assert_array_equal(jt.v[list(ct.corner_indices)], 0.0)


def test_circle_joint_trajectory_accelerations(arm):
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
    _check_consistent(jt)


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
def test_square_property_fk_reproduction(arm, radius, angle, side, edge_angle):
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
    _check_consistent(jt)


def test_square_across_the_angle_wrap_needs_unwrap(arm):
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
    _check_consistent(jt)


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
