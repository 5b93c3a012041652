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

from mbctl.planners import (
    InvalidLimits,
    InvalidPlanningInput,
    JointLimits,
    JointTrajectory,
    PlanningError,
    TrajectoryGenerationFailed,
    cubic_trajectory,
    minimum_jerk_at,
    minimum_jerk_trajectory,
    pass_through_velocities,
    plan_ruckig,
    plan_waypoints,
    quintic_trajectory,
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
def test_ruckig_reaches_target_exactly_within_limits_and_synchronized(check_consistent):
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
    check_consistent(traj)
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


def test_ruckig_profile_boundary_input_is_retried(check_consistent):
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
    check_consistent(traj)
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


def test_waypoints_pass_through_every_waypoint_and_stop(check_consistent):
    wps = np.array([[0.0, 0.0, 0.0], [0.5, -0.2, 0.1], [0.5, 0.4, -0.3], [-0.1, 0.0, 0.0]])
    traj = plan_waypoints(wps, LIMITS3, DT, NAMES3)
    np.testing.assert_allclose(np.diff(traj.t_s), DT, rtol=1e-9)
    hits = [int(np.flatnonzero(np.all(traj.q == w, axis=1))[0]) for w in wps]
    assert hits == sorted(hits) and hits[0] == 0 and hits[-1] == len(traj.t_s) - 1
    np.testing.assert_array_equal(traj.v[hits], 0.0)
    _check_limits(traj, LIMITS3)
    check_consistent(traj)


def test_waypoints_pass_through_with_velocities():
    wps = np.array([[0.0, 0.0, 0.0], [0.5, 0.3, 0.2], [1.0, 0.6, 0.4]])
    vels = np.array([[0.0, 0.0, 0.0], [0.5, 0.3, 0.2], [0.0, 0.0, 0.0]])
    traj = plan_waypoints(wps, LIMITS3, DT, NAMES3, waypoint_velocities=vels)
    k = int(np.flatnonzero(np.all(traj.q == wps[1], axis=1))[0])
    np.testing.assert_array_equal(traj.v[k], vels[1])
    _check_limits(traj, LIMITS3)
    stop = plan_waypoints(wps, LIMITS3, DT, NAMES3)
    assert traj.duration_s < stop.duration_s


def test_waypoints_pass_through_heuristic(check_consistent):
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
    check_consistent(traj)
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
def test_quintic_boundary_conditions_exact(check_consistent, q0, q1, v0, v1, a0, a1, duration):
    traj = quintic_trajectory(q0, q1, duration, 0.01, ("a", "b"), v0, v1, a0, a1)
    for got, want in ((traj.q[0], q0), (traj.v[0], v0), (traj.a[0], a0),
                      (traj.q[-1], q1), (traj.v[-1], v1), (traj.a[-1], a1)):
        np.testing.assert_array_equal(got, want)
    assert traj.duration_s >= duration - 1e-9 and traj.duration_s < duration + 0.01
    check_consistent(traj)
    # Accelerations agree with central differences of v (error dt^2 / 6 |snap|).
    dt = traj.dt_s
    a_fd = (traj.v[2:] - traj.v[:-2]) / (2 * dt)
    snap = float(np.max(np.abs(np.diff(traj.a, 2, axis=0)))) / dt**2
    bound = 1.5 * dt**2 / 6 * snap + 1e-9 * max(1.0, float(np.max(np.abs(traj.a))))
    assert np.max(np.abs(a_fd - traj.a[1:-1])) <= bound


@settings(max_examples=30, deadline=None)
@given(vec2, vec2, vec2, vec2, st.floats(0.2, 3.0))
def test_cubic_boundary_conditions_exact(check_consistent, q0, q1, v0, v1, duration):
    traj = cubic_trajectory(q0, q1, duration, 0.01, ("a", "b"), v0, v1)
    for got, want in ((traj.q[0], q0), (traj.v[0], v0), (traj.q[-1], q1), (traj.v[-1], v1)):
        np.testing.assert_array_equal(got, want)
    # A cubic has constant jerk: second differences of a vanish.
    assert np.max(np.abs(np.diff(traj.a, 2, axis=0))) < 1e-9 * max(1.0, np.max(np.abs(traj.a)))
    check_consistent(traj)


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


def test_minimum_jerk_at_one_time_equals_the_sampled_trajectory_and_holds_outside():
    q0, q1, T, t0 = np.array([0.2, -1.0]), np.array([1.2, 0.5]), 2.0, 0.5
    traj = minimum_jerk_trajectory(q0, q1, T, 0.01, ("a", "b"))
    for k in (0, 37, 100, 163, 200):
        p, v, a = minimum_jerk_at(q0, q1, t0 + traj.t_s[k], t0, T)
        np.testing.assert_allclose(p, traj.q[k], atol=1e-13)
        np.testing.assert_allclose(v, traj.v[k], atol=1e-12)
        np.testing.assert_allclose(a, traj.a[k], atol=1e-11)
    for t, held in ((t0 - 0.3, q0), (t0 + T + 0.3, q1)):
        p, v, a = minimum_jerk_at(q0, q1, t, t0, T)
        np.testing.assert_array_equal(p, held)
        assert not v.any() and not a.any()
        p += 1.0  # new arrays: a caller may change them (the squat lowers its target in place)
        v += 1.0
        assert held[0] in (0.2, 1.2) and not a.any()
    with pytest.raises(InvalidPlanningInput, match="duration_s"):
        minimum_jerk_at(q0, q1, 0.0, 0.0, 0.0)


def test_polynomial_duration_rounding_and_bad_inputs():
    traj = minimum_jerk_trajectory([0.0], [1.0], 0.333, 0.01, ("a",))
    assert len(traj.t_s) == 35 and traj.duration_s == pytest.approx(0.34)
    with pytest.raises(InvalidPlanningInput, match=r"duration_s must be finite and > 0 \[s\]"):
        minimum_jerk_trajectory([0.0], [1.0], 0.0, 0.01, ("a",))
    with pytest.raises(InvalidPlanningInput, match=r"target_velocity must have shape \(1,\)"):
        cubic_trajectory([0.0], [1.0], 1.0, 0.01, ("a",), target_velocity=[1.0, 2.0])
    with pytest.raises(InvalidPlanningInput, match="dt_s must be finite and > 0"):
        quintic_trajectory([0.0], [1.0], 1.0, -0.01, ("a",))
