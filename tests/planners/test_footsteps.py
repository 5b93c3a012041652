"""Footsteps: limits from the G1's model, the command clamp and its report, placement, waypoints."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mbctl.planners import InvalidLimits, InvalidPlanningInput
from mbctl.planners.footsteps import (
    Footstep,
    FootstepPlanner,
    GaitTiming,
    StepLimits,
    VelocityCommand,
    WaypointFollower,
    leg_chain,
    step_limits_from_model,
)

FEET = ("left_foot", "right_foot")
#: The G1 sole's contact points (m) in the foot frame (control.wbc.foot_contact_from_model's, 35 mm below).
SOLE_F = np.array([[-0.05, 0.025, -0.035], [-0.05, -0.025, -0.035], [0.12, 0.03, -0.035],
                   [0.12, -0.03, -0.035]])
LIMITS = StepLimits(max_forward_m=0.36, max_backward_m=0.2, max_outward_m=0.2, nominal_width_m=0.24,
                    min_width_m=0.1, max_yaw_rad=0.6)
TIMING = GaitTiming(0.5, 0.1)  # T = 0.6 s


@pytest.fixture(scope="module")
def crouched(g1):
    from mbctl.robots.g1 import crouched_start

    return crouched_start(g1)


def test_g1_limits_from_its_model(g1, crouched):
    lim = step_limits_from_model(g1, FEET, SOLE_F, crouched, 0.64)
    # the hip: the leg's first joint, the hip pitch; L from it to the sole at the neutral (straight) pose
    model, data = g1.pin_model, g1.pin_model.createData()
    assert [model.names[j] for j in leg_chain(g1, "left_foot")][:3] == [
        "left_hip_pitch_joint", "left_hip_roll_joint", "left_hip_yaw_joint"]
    pin.framesForwardKinematics(model, data, pin.neutral(model))
    sole = data.oMf[model.getFrameId("left_foot")].translation - [0, 0, 0.035]
    L = np.linalg.norm(sole - data.oMi[model.getJointId("left_hip_pitch_joint")].translation)
    assert L == pytest.approx(0.6913, abs=1e-4)
    com = pin.centerOfMass(model, data, crouched)
    h = 0.64 - (com[2] - data.oMi[model.getJointId("left_hip_pitch_joint")].translation[2])
    reach = math.sqrt((0.97 * L) ** 2 - h**2)
    assert lim.max_forward_m == pytest.approx(2 * 0.8 * reach, rel=1e-9)
    assert 0.35 < lim.max_forward_m < 0.40  # 0.374 m at a 0.64 m CoM
    assert lim.max_backward_m == pytest.approx(0.6 * lim.max_forward_m, rel=1e-12)
    assert lim.max_outward_m == pytest.approx(reach, rel=1e-9)
    assert lim.nominal_width_m == pytest.approx(0.2370, abs=1e-4)  # the feet's y at the keyframe: +-0.1185
    assert lim.min_width_m == pytest.approx(0.06 + 0.04, abs=1e-12)  # the sole's width + the clearance
    assert lim.max_yaw_rad == pytest.approx(0.25 * 2.7576, abs=1e-9)  # a quarter of the hip-yaw range
    assert sorted(lim.sole_xy_m) == sorted(map(tuple, SOLE_F[:, :2]))  # the sole's outline
    # a lower CoM reaches further; one the legs cannot reach is refused
    assert step_limits_from_model(g1, FEET, SOLE_F, crouched, 0.60).max_forward_m > lim.max_forward_m
    with pytest.raises(InvalidPlanningInput, match="lower the CoM"):
        step_limits_from_model(g1, FEET, SOLE_F, crouched, 0.70)


def test_a_command_within_the_limits_is_applied_as_given():
    clamp = FootstepPlanner(LIMITS, TIMING, FEET).clamp((0.3, 0.05, 0.2))
    assert clamp.applied == clamp.requested == VelocityCommand(0.3, 0.05, 0.2)
    assert not clamp.clamped and clamp.limited_by == ()


@pytest.mark.parametrize("command, applied, limits", [
    ((1.0, 0.0, 0.0), (0.6, 0.0, 0.0), ("forward step",)),  # 0.36 m / 0.6 s
    ((-1.0, 0.0, 0.0), (-1 / 3, 0.0, 0.0), ("backward step",)),  # 0.2 m / 0.6 s
    ((0.0, -0.5, 0.0), (0.0, -1 / 6, 0.0), ("lateral step",)),  # 0.2 m / (2 x 0.6 s)
    ((0.0, 0.0, 2.0), (0.0, 0.0, 1.0), ("yaw per step",)),  # 0.6 rad / 0.6 s
])
def test_each_limit_clamps_and_is_reported(command, applied, limits):
    clamp = FootstepPlanner(LIMITS, TIMING, FEET).clamp(command)
    np.testing.assert_allclose(clamp.applied, applied, atol=1e-12)
    assert clamp.limited_by == limits and clamp.clamped and clamp.requested == VelocityCommand(*command)


def test_forward_and_lateral_together_are_scaled_onto_the_reach_ellipse():
    clamp = FootstepPlanner(LIMITS, TIMING, FEET).clamp((0.5, 0.15, 0.0))
    vx, vy, _ = clamp.applied
    assert math.hypot(vx / 0.6, vy / (1 / 6)) == pytest.approx(1.0, abs=1e-12)
    assert vx / vy == pytest.approx(0.5 / 0.15, rel=1e-12)  # the direction is kept
    assert clamp.limited_by == ("reach (forward and lateral together)",)
    with pytest.raises(InvalidPlanningInput, match="finite"):
        FootstepPlanner(LIMITS, TIMING, FEET).clamp((float("nan"), 0, 0))


def _from_rest():
    return Footstep("right_foot", -1, np.array([0.0, -0.12, 0.0]), 0.0)


def test_walking_straight_alternates_the_feet_at_the_nominal_width():
    steps = FootstepPlanner(LIMITS, TIMING, FEET).plan(_from_rest(), VelocityCommand(0.4, 0.0, 0.0), 6)
    assert [s.foot for s in steps] == ["left_foot", "right_foot"] * 3
    assert [s.side for s in steps] == [1, -1] * 3
    xs = [s.position[0] for s in steps]
    np.testing.assert_allclose(np.diff([0.0, *xs]), 0.24, atol=1e-12)  # vx T
    np.testing.assert_allclose([s.position[1] for s in steps], [0.12, -0.12] * 3, atol=1e-12)


@pytest.mark.parametrize("vy", [0.1, -0.1])
def test_sideways_the_leading_foot_steps_out_and_the_other_closes(vy):
    planner = FootstepPlanner(LIMITS, TIMING, FEET)
    steps = planner.plan(_from_rest(), VelocityCommand(0.0, vy, 0.0), 8)
    widths = [abs(b.position[1] - a.position[1]) for a, b in zip([_from_rest(), *steps], steps, strict=False)]
    assert sorted(set(np.round(widths, 12))) == [0.24, round(0.24 + 2 * abs(vy) * 0.6, 12)]
    # over a stride (two steps) both feet move 2 vy T: the body's speed is vy
    assert steps[-1].position[1] - steps[-3].position[1] == pytest.approx(2 * vy * 0.6, abs=1e-12)


def test_turning_rotates_every_footstep_by_the_yaw_rate_times_the_period():
    steps = FootstepPlanner(LIMITS, TIMING, FEET).plan(_from_rest(), VelocityCommand(0.2, 0.0, 0.5), 10)
    np.testing.assert_allclose(np.diff([0.0] + [s.yaw_rad for s in steps]), 0.3, atol=1e-12)


def test_feet_never_cross_under_random_commands():
    rng = np.random.default_rng(7)
    planner = FootstepPlanner(LIMITS, TIMING, FEET)
    stance = _from_rest()
    for _ in range(400):
        command = planner.clamp(rng.uniform([-1, -0.5, -2], [1, 0.5, 2])).applied
        step = planner.next_footstep(stance, command)
        c, s = math.cos(stance.yaw_rad), math.sin(stance.yaw_rad)
        d = step.position - stance.position
        width = step.side * (-s * d[0] + c * d[1])  # toward the step's side, in the stance heading frame
        assert LIMITS.min_width_m <= width
        assert width <= LIMITS.nominal_width_m + LIMITS.max_outward_m + 1e-12
        assert abs(math.remainder(step.yaw_rad - stance.yaw_rad, 2 * math.pi)) <= LIMITS.max_yaw_rad + 1e-12
        stance = step


SOLE_LIMITS = StepLimits(max_forward_m=0.36, max_backward_m=0.2, max_outward_m=0.2, nominal_width_m=0.24,
                         min_width_m=0.1, max_yaw_rad=0.6, sole_xy_m=tuple(map(tuple, SOLE_F[:, :2])))


def _sole_gap(stance: Footstep, step: Footstep) -> float:
    """How far [m] the step's sole is beyond the stance sole's inner edge, across the stance heading."""
    c, s = math.cos(stance.yaw_rad), math.sin(stance.yaw_rad)
    lateral = [(-s * p[0] + c * p[1]) * step.side
               for p in (step.point_W(x) - stance.position for x in SOLE_F)]
    return min(lateral) - max(step.side * SOLE_F[:, 1])


@given(st.floats(-0.6, 0.6), st.floats(-0.5, 0.5), st.floats(-0.3, 0.5), st.floats(-math.pi, math.pi),
       st.sampled_from([1, -1]))
@settings(max_examples=300, deadline=None)
def test_a_turned_footstep_keeps_its_sole_clear_of_the_stance_sole(dyaw, lat, fwd, heading, side):
    planner = FootstepPlanner(SOLE_LIMITS, TIMING, FEET)
    stance = Footstep(FEET[side > 0], -side, np.array([0.3, -0.2, 0.0]), heading)
    c, s = math.cos(heading), math.sin(heading)
    step = Footstep(FEET[side < 0], side, stance.position + [c * fwd - s * lat, s * fwd + c * lat, 0.0],
                    heading + dyaw)
    limited, _ = planner.limit_step(stance, step)
    # the clearance (min width - the sole's 6 cm) holds between the soles, whatever the turn
    assert _sole_gap(stance, limited) >= 0.1 - 0.06 - 1e-9


def test_the_width_bound_grows_with_a_turn_toward_the_stance_foot():
    # a right footstep turned 0.3 rad to the left: its toe (0.12 m ahead) swings 36 mm toward the left sole
    width = SOLE_LIMITS.min_width_for(0.3, -1)
    assert width == pytest.approx(0.04 + 0.03 + math.sin(0.3) * 0.12 + math.cos(0.3) * 0.03, abs=1e-12)
    assert SOLE_LIMITS.min_width_for(0.0, -1) == pytest.approx(0.1, abs=1e-12)  # unturned: the plain bound
    assert LIMITS.min_width_for(0.3, -1) == 0.1  # no sole outline: the plain bound
    planner = FootstepPlanner(SOLE_LIMITS, TIMING, FEET)
    stance = Footstep("left_foot", 1, np.zeros(3), 0.0)
    step, moved = planner.limit_step(stance, Footstep("right_foot", -1, np.array([0.1, -0.1, 0.0]), 0.3))
    assert moved and step.position[1] == pytest.approx(-width, abs=1e-12)
    assert _sole_gap(stance, step) == pytest.approx(0.04, abs=1e-12)  # the clearance, exactly
    with pytest.raises(InvalidLimits, match="sole_xy_m"):
        StepLimits(0.3, 0.2, 0.2, 0.2, 0.1, 0.5, ((0.0, 0.0), (1.0, 0.0)))


def test_limit_step_projects_a_footstep_into_the_box():
    planner = FootstepPlanner(LIMITS, TIMING, FEET)
    stance = Footstep("right_foot", -1, np.array([1.0, 2.0, 0.0]), math.pi / 2)  # heading +y
    inside = Footstep("left_foot", 1, np.array([0.8, 2.1, 0.0]), math.pi / 2)  # 0.1 ahead, 0.2 to its left
    assert planner.limit_step(stance, inside) == (inside, False)
    crossing = Footstep("left_foot", 1, np.array([1.05, 2.7, 0.0]), math.pi / 2 + 1.0)
    step, moved = planner.limit_step(stance, crossing)
    assert moved
    np.testing.assert_allclose(step.position, [0.9, 2.36, 0.0], atol=1e-12)  # width 0.1, 0.36 ahead
    assert step.yaw_rad == pytest.approx(math.pi / 2 + 0.6, abs=1e-12)


def test_waypoints_are_followed_in_turn_and_reported():
    follower = WaypointFollower([[1.0, 0.0, 0.0], [1.0, 1.0, math.pi / 2]], position_tolerance_m=0.05)
    cmd = follower.command([0.0, 0.0, 0.0], 0.0)
    assert cmd == VelocityCommand(1.0, 0.0, 0.0)  # gain 1/s times the error in the body frame
    cmd = follower.command([0.98, 0.0, 0.0], 1.5)  # within 5 cm of the first: on to the second
    assert follower.index == 1 and follower.reached_at_s[0] == 1.5
    bearing = math.atan2(1.0, 0.02)  # 1 m away, nearly to the left: face it, slowly, half the side step
    assert tuple(cmd) == pytest.approx((0.02 * math.cos(bearing), 0.5, bearing))
    near = follower.command([1.0, 0.8, math.pi / 2], 2.0)  # 0.2 m short (within 0.3 m): to its heading
    assert tuple(near) == pytest.approx((0.2, 0.0, 0.0), abs=1e-12)
    cmd = follower.command([1.0, 1.0, math.pi / 2 - 0.01], 4.0)
    assert follower.done and follower.reached_at_s[1] == 4.0
    assert tuple(cmd) == pytest.approx((0.0, 0.0, 0.01), abs=1e-12)  # the last one held: its heading
    assert follower.errors([1.0, 1.0, math.pi / 2 - 0.01]) == pytest.approx((0.0, 0.01))
    # past it by 8 cm (forward, facing +y): back to it, within reach of its heading (no turn to face it)
    back = follower.command([1.0, 1.08, math.pi / 2], 5.0)
    assert tuple(back) == pytest.approx((-0.08, 0.0, 0.0), abs=1e-12) and follower.reached_at_s[1] == 4.0


def test_invalid_limits_and_timing_name_the_value():
    with pytest.raises(InvalidLimits, match="single_support_s"):
        GaitTiming(0.1, 0.1)
    with pytest.raises(InvalidLimits, match="min_width_m"):
        StepLimits(0.3, 0.2, 0.2, 0.2, 0.3, 0.5)
    with pytest.raises(InvalidPlanningInput, match="waypoints"):
        WaypointFollower([[0.0, 1.0]])
