"""The swing foot's path: at rest at lift-off and touchdown, the apex, continuity when the footstep moves."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mbctl.planners import InvalidPlanningInput, quintic_trajectory
from mbctl.planners.swing import MIN_RETARGET_S, SwingTrajectory, polynomial_at, quintic_coefficients

START, TARGET = np.array([0.0, 0.12, 0.035]), np.array([0.25, 0.10, 0.035])


def _swing(**kw):
    args = dict(start_position=START, start_yaw_rad=0.1, target_position=TARGET, target_yaw_rad=0.4,
                duration_s=0.5, lift_height_m=0.07, t0_s=2.0)
    args.update(kw)
    return SwingTrajectory(**args)


def test_quintic_coefficients_are_the_planners_closed_form():
    names = ["a", "b"]
    traj = quintic_trajectory([0.1, -0.2], [0.5, 0.3], 0.4, 0.01, names, current_velocity=[0.2, 0.0],
                              target_velocity=[0.0, -0.1], current_acceleration=[1.0, 0.0],
                              target_acceleration=[0.0, 2.0])
    c = quintic_coefficients([0.1, -0.2], [0.2, 0.0], [1.0, 0.0], [0.5, 0.3], [0.0, -0.1], [0.0, 2.0], 0.4)
    for k in (0, 13, 27, 40):
        p, v, a = polynomial_at(c, traj.t_s[k])
        np.testing.assert_allclose(p, traj.q[k], atol=1e-12)
        np.testing.assert_allclose(v, traj.v[k], atol=1e-11)
        np.testing.assert_allclose(a, traj.a[k], atol=1e-9)


def test_quintic_end_values_of_other_lengths_are_named():
    with pytest.raises(InvalidPlanningInput, match=r"scalars or vectors of one length .*\(2,\), \(3,\)"):
        quintic_coefficients([0.0, 1.0], [0.0, 0.0, 0.0], 0.0, 1.0, 0.0, 0.0, 0.5)
    with pytest.raises(InvalidPlanningInput, match=r"\(2, 2\)"):
        quintic_coefficients(np.zeros((2, 2)), 0.0, 0.0, 1.0, 0.0, 0.0, 0.5)


def test_the_foot_leaves_and_lands_at_rest_on_its_footstep():
    s = _swing()
    first, last = s.at(2.0), s.at(2.5)
    np.testing.assert_allclose(first.position, START, atol=1e-12)
    np.testing.assert_allclose(last.position, TARGET, atol=1e-12)
    for sample in (first, last):
        assert np.abs(sample.velocity).max() < 1e-12 and np.abs(sample.acceleration).max() < 1e-12
        assert abs(sample.yaw_rate_rad_s) < 1e-12
    assert (first.yaw_rad, last.yaw_rad) == pytest.approx((0.1, 0.4), abs=1e-12)
    # 5 ms before touchdown the foot descends at 30 s^2 (1 - s)^2 dz / T = 3.2 mm/s (s = 0.98 of the
    # descent's T = 0.25 s, dz = 7 cm: the minimum-jerk approach); forward, s = 0.99 of 0.5 s for 25 cm
    near = s.at(2.5 - 0.005)
    assert near.velocity[2] == pytest.approx(-30 * 0.98**2 * 0.02**2 * 0.07 / 0.25, rel=1e-9)
    assert near.velocity[0] == pytest.approx(30 * 0.99**2 * 0.01**2 * 0.25 / 0.5, rel=1e-9)
    # before and after the swing it holds its ends
    np.testing.assert_allclose(s.at(1.0).position, START, atol=1e-12)
    np.testing.assert_allclose(s.at(9.0).position, TARGET, atol=1e-12)
    assert (s.at(1.0).phase, s.at(2.25).phase, s.at(9.0).phase) == (0.0, 0.5, 1.0)


def test_the_apex_is_the_lift_height_at_mid_swing_with_zero_vertical_speed():
    s = _swing(target_position=TARGET + [0, 0, 0.02])  # a step up 2 cm: the apex is above the higher end
    apex = s.at(2.25)
    assert apex.position[2] == pytest.approx(0.055 + 0.07, abs=1e-12)
    assert abs(apex.velocity[2]) < 1e-12 and abs(apex.acceleration[2]) < 1e-9
    heights = [s.at(2.0 + k * 0.005).position[2] for k in range(101)]
    assert max(heights) == pytest.approx(0.125, abs=1e-12) and min(heights) == pytest.approx(0.035, abs=1e-12)


def test_velocity_and_acceleration_are_the_derivatives_of_the_path():
    s = _swing(horizontal_fraction=0.8)
    h = 1e-6  # the vertical jerk changes sign at the apex: the difference errs by |jerk| h there
    for t in np.linspace(2.01, 2.49, 17):
        a, b, mid = s.at(t - h), s.at(t + h), s.at(t)
        np.testing.assert_allclose((b.position - a.position) / (2 * h), mid.velocity, atol=1e-6)
        np.testing.assert_allclose((b.velocity - a.velocity) / (2 * h), mid.acceleration, atol=5e-4)
        assert (b.yaw_rad - a.yaw_rad) / (2 * h) == pytest.approx(mid.yaw_rate_rad_s, abs=1e-6)
        assert (b.yaw_rate_rad_s - a.yaw_rate_rad_s) / (2 * h) == pytest.approx(mid.yaw_acceleration_rad_s2,
                                                                                abs=5e-4)


def test_horizontal_motion_ends_first_then_the_foot_descends_vertically():
    s = _swing(horizontal_fraction=0.8)
    late = s.at(2.0 + 0.85 * 0.5)
    np.testing.assert_allclose(late.position[:2], TARGET[:2], atol=1e-12)
    assert late.velocity[0] == late.velocity[1] == 0.0 and late.velocity[2] < -0.1
    assert late.yaw_rad == pytest.approx(0.4, abs=1e-12)


def test_retarget_keeps_the_path_twice_differentiable_and_lands_on_the_new_footstep():
    s = _swing()
    t = 2.2
    before = s.at(t)
    new = np.array([0.30, 0.14, 0.0])
    assert s.retarget(t, new, 0.5) is True
    after = s.at(t)
    np.testing.assert_allclose(after.position, before.position, atol=1e-12)
    np.testing.assert_allclose(after.velocity, before.velocity, atol=1e-12)
    np.testing.assert_allclose(after.acceleration, before.acceleration, atol=1e-10)
    end = s.at(2.5)
    np.testing.assert_allclose(end.position, [0.30, 0.14, TARGET[2]], atol=1e-12)  # the height stays
    assert np.abs(end.velocity).max() < 1e-12 and end.yaw_rad == pytest.approx(0.5, abs=1e-12)
    # too late: frozen
    assert s.retarget(2.5 - 0.5 * MIN_RETARGET_S, [1.0, 1.0, 0.0], 0.0) is False
    np.testing.assert_allclose(s.at(2.5).position[:2], [0.30, 0.14], atol=1e-12)


@pytest.mark.parametrize("t", [2.08, 2.2])  # before the new apex, and after it (straight down)
def test_a_retimed_swing_reaches_its_footstep_at_rest_at_its_new_touchdown(t):
    s = _swing(horizontal_fraction=0.8)
    before = s.at(t)
    assert s.retime(t, 0.32) is True
    assert s.end_s == pytest.approx(2.32, abs=1e-12) and s.duration_s == pytest.approx(0.32, abs=1e-12)
    after = s.at(t)  # continuous: position, velocity and acceleration
    np.testing.assert_allclose(after.position, before.position, atol=1e-12)
    np.testing.assert_allclose(after.velocity, before.velocity, atol=1e-10)
    np.testing.assert_allclose(after.acceleration, before.acceleration, atol=1e-8)
    # the horizontal motion ends at 0.8 of the new swing; the foot is down on its footstep at its end, at rest
    np.testing.assert_allclose(s.at(2.0 + 0.8 * 0.32).position[:2], TARGET[:2], atol=1e-12)
    end = s.at(2.32 - 1e-9)
    np.testing.assert_allclose(end.position, TARGET, atol=1e-9)
    assert np.abs(end.velocity).max() < 1e-6 and end.phase == pytest.approx(1.0)
    # above the footstep's height all the way (no dip through the ground)
    heights = [s.at(u).position[2] for u in np.linspace(t, 2.32, 50)]
    assert min(heights) >= TARGET[2] - 1e-12
    # too late to re-time: unchanged
    assert s.retime(2.3, 0.35) is False and s.end_s == pytest.approx(2.32)


def test_yaw_goes_the_short_way():
    s = _swing(start_yaw_rad=3.0, target_yaw_rad=-3.0)  # 0.28 rad through pi, not 6 rad back
    assert s.at(2.5).yaw_rad == pytest.approx(-3.0 + 2 * math.pi, abs=1e-12)


@pytest.mark.parametrize("kw, word", [
    (dict(duration_s=0.0), "duration_s"), (dict(lift_height_m=-0.01), "lift_height_m"),
    (dict(target_position=[0.0, 0.0]), "target_position"),
    (dict(horizontal_fraction=0.0), "horizontal_fraction"),
    (dict(start_yaw_rad=float("nan")), "start_yaw_rad"),
])
def test_bad_input_names_the_argument(kw, word):
    with pytest.raises(InvalidPlanningInput, match=word):
        _swing(**kw)


def test_yaw_at_is_the_samples_yaw_and_a_retarget_moves_the_held_footstep():
    swing = _swing()
    for t in (1.9, 2.0, 2.1, 2.25, 2.399, 2.45, 2.6):
        assert swing.yaw_at(t) == swing.at(t).yaw_rad
    # after the horizontal motion (0.5 s: the default fraction 1 ends it with the swing) the sample holds
    # the footstep; a retarget (at an earlier time) moves what is held there
    end = swing.at(2.5)
    np.testing.assert_allclose(end.position[:2], TARGET[:2], atol=1e-12)
    assert end.yaw_rad == pytest.approx(0.4, abs=1e-12)
    swing.retarget(2.2, [0.3, 0.05, 0.0], 0.2)
    held = swing.at(2.6)
    np.testing.assert_allclose(held.position[:2], [0.3, 0.05], atol=1e-12)
    assert held.yaw_rad == pytest.approx(0.2, abs=1e-12) and swing.yaw_at(2.6) == held.yaw_rad
