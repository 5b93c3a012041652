"""After a push: the stiffer DCM law and the hurried next step in double support, the wider pushed step.

The walker (conftest.py's biped in MuJoCo) walks to its first touchdown; there, a state whose CoM
moves sideways faster than the plan's (as after a push) puts the DCM off its plan, and the cycle's
desired CMP and the gait's timing are checked against the law, number by number.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from mbctl.control import run
from mbctl.control.exceptions import WBCSetupError
from mbctl.control.wbc import StepAdapter, WalkingConfig, WalkingController, WBCConfig
from mbctl.planners import Footstep, FootstepPlanner, GaitTiming, StepLimits
from mbctl.robots.interface import RobotState
from mbctl.sim import Simulator

FEET = ("l_sole", "r_sole")
CONFIG = WalkingConfig(com_height_m=0.5, wbc=WBCConfig(on_infeasible="damp"))


def _to_first_touchdown(robot, crouch, config=CONFIG) -> tuple[WalkingController, Simulator]:
    """The walker and the plant at the cycle of the first touchdown (walking 0.15 m/s forward)."""
    q0 = crouch(robot)
    sim = Simulator(robot)
    sim.set_state(q0, np.zeros(robot.nv))
    walker = WalkingController(robot, FEET, "pelvis", "torso", q0, config,
                               contact_force=lambda f: None)
    walker.set_command((0.15, 0.0, 0.0))

    def on_step(k, state, ref, cmd):
        event = walker.status.event
        return event is not None and event.kind == "touchdown"

    run(sim, walker, None, 2.0, on_step=on_step)
    assert walker.status.event is not None and walker.status.event.kind == "touchdown"
    return walker, sim


def _pushed(state: RobotState, dv_y_m_s: float) -> RobotState:
    """``state`` with the floating base moving ``dv_y_m_s`` [m/s] faster along W's y (its linear velocity)."""
    v = state.v.copy()
    v[1] += dv_y_m_s  # Pinocchio's free-flyer velocity is in the base frame: upright here, yaw ~0
    return state._replace(time_s=state.time_s + 0.002, v=v)


def test_a_push_in_double_support_stiffens_the_dcm_law_and_hurries_the_next_step(tiny_biped, crouch):
    walker, sim = _to_first_touchdown(tiny_biped, crouch)
    gait, cfg = walker.gait, walker.config
    assert gait.phase == "double" and gait.releasing is None
    t_down = walker.status.time_s
    planned_end = gait.phase_end
    assert planned_end - t_down >= cfg.timing.double_support_s - 1e-9  # 0.1 s of double support ahead
    state = _pushed(sim.read_state(), 0.4)  # the CoM 0.4 m/s sideways: the DCM ~0.4 / omega = 0.09 m off
    walker.compute(state)
    s = walker.status
    error = s.dcm - s.dcm_ref
    assert np.linalg.norm(error) > cfg.hurry_after_m > cfg.cmp_outside_after_m
    # the desired CMP: the plan's VRP plus (1 + k / omega) times the error, k the hurried double support's
    # 15 (the error beyond hurry_after_m; the pushed one's 8 from cmp_outside_after_m to there)
    k = cfg.hurried_double_gain_1_s
    assert (k, cfg.pushed_double_gain_1_s) == (15.0, 8.0)
    np.testing.assert_allclose(s.cmp, s.zmp_ref + (1.0 + k / walker.omega) * error, atol=1e-12)
    assert not np.allclose(s.cmp, s.zmp_ref + (1.0 + 8.0 / walker.omega) * error, atol=1e-3)
    assert not np.allclose(s.cmp, s.zmp_ref + (1.0 + cfg.dcm_gain_1_s / walker.omega) * error, atol=1e-3)
    # and the trailing foot is released now: the double support ends one force ramp later, not 0.1 s on
    assert gait.phase_end == pytest.approx(state.time_s + cfg.ramp_s, abs=1e-12)
    assert gait.phase_end < planned_end - 0.04
    walker.compute(state._replace(time_s=state.time_s + 0.002))
    assert walker.status.event is not None and walker.status.event.kind == "release"
    assert walker.status.event.foot != gait.leading


def test_undisturbed_double_support_keeps_the_dcm_law_and_its_timing(tiny_biped, crouch):
    walker, sim = _to_first_touchdown(tiny_biped, crouch)
    gait, cfg = walker.gait, walker.config
    planned_end = gait.phase_end
    state = sim.read_state()._replace(time_s=sim.read_state().time_s + 0.002)
    walker.compute(state)
    s = walker.status
    error = s.dcm - s.dcm_ref
    assert np.linalg.norm(error) < cfg.cmp_outside_after_m  # within 3 cm: the walk as planned
    np.testing.assert_allclose(s.cmp, s.zmp_ref + (1.0 + cfg.dcm_gain_1_s / walker.omega) * error, atol=1e-12)
    assert gait.phase_end == planned_end


def test_hurry_acts_only_in_double_support_after_a_touchdown(tiny_biped, crouch):
    walker, sim = _to_first_touchdown(tiny_biped, crouch, replace(CONFIG, hurry_after_m=math.inf))
    gait = walker.gait
    t = walker.status.time_s
    revision = gait.revision
    gait.hurry(t + 0.2)  # later than the planned end: nothing to hurry
    assert gait.revision == revision
    gait.hurry(t)
    assert gait.phase_end == pytest.approx(t + walker.config.ramp_s) and gait.revision == revision + 1
    end = gait.phase_end
    gait.releasing = "r_sole"  # once the release started, the timing stays
    gait.hurry(t - 0.01)
    assert gait.phase_end == end


@pytest.mark.parametrize("field, value", [("pushed_double_gain_1_s", 0.0), ("hurry_after_m", 0.0),
                                          ("hurried_double_gain_1_s", 0.0),
                                          ("hurried_double_gain_1_s", math.inf),
                                          ("hurry_after_m", -1.0), ("pushed_double_gain_1_s", math.nan)])
def test_the_push_options_are_checked(field, value):
    with pytest.raises(WBCSetupError, match=field):
        WalkingConfig(**{field: value})


LIMITS = StepLimits(0.36, 0.2, 0.2, 0.24, 0.1, 0.6)
OMEGA = math.sqrt(9.81 / 0.64)


def test_a_pushed_step_may_go_further_outward_toward_the_dcm():
    planner = FootstepPlanner(LIMITS, GaitTiming(0.5, 0.1), ("left", "right"))
    adapter = StepAdapter(planner, OMEGA, (0.02, 0.005), pushed_outward_m=1.6 * LIMITS.max_outward_m)
    stance = Footstep("right", -1, np.array([0.0, 0.0, 0.0]), 0.0)
    nominal = Footstep("left", 1, np.array([0.0, 0.24, 0.0]), 0.0)  # in place: the reach 8-gon's widest
    error = [0.0, 0.08]  # a push to the swing side, 0.3 s before the switch: the DCM needs 0.24 m more
    needed = nominal.position[1] + math.exp(OMEGA * 0.3) * (error[1] - 0.005) / (1 + adapter.nominal_weight)
    assert needed == pytest.approx(0.4803, abs=1e-4)
    walking = adapter.adapt(stance, nominal, error, 0.3)
    pushed = adapter.adapt(stance, nominal, error, 0.3, pushed=True)
    # walking: held at the planner's widest step (0.24 + 0.2 from the stance), 4 cm short, reported
    assert walking.limited and walking.footstep.position[1] == pytest.approx(0.44, abs=1e-6)
    # pushed: the limit is 0.24 + 1.6 x 0.2 = 0.56 m out, so the footstep goes where the DCM needs it
    assert not pushed.limited and pushed.footstep.position[1] == pytest.approx(needed, abs=1e-6)
    further = adapter.adapt(stance, nominal, [0.0, 0.12], 0.3, pushed=True)  # needs 0.37: held at 0.56
    assert further.limited and further.footstep.position[1] == pytest.approx(0.56, abs=1e-6)
    # a smaller error the wider limit does not bind: the same footstep either way
    small = [0.0, 0.03]
    np.testing.assert_allclose(adapter.adapt(stance, nominal, small, 0.3, pushed=True).footstep.position,
                               adapter.adapt(stance, nominal, small, 0.3).footstep.position, atol=1e-12)
    with pytest.raises(WBCSetupError, match="pushed_outward_m"):
        StepAdapter(planner, OMEGA, (0.02, 0.005), pushed_outward_m=0.0)


def _to_swing_phase(robot, crouch, phase: float, config=CONFIG) -> tuple[WalkingController, Simulator]:
    """The walker and the plant once the first swing is ``phase`` of the way through."""
    q0 = crouch(robot)
    sim = Simulator(robot)
    sim.set_state(q0, np.zeros(robot.nv))
    walker = WalkingController(robot, FEET, "pelvis", "torso", q0, config, contact_force=lambda f: None)
    walker.set_command((0.15, 0.0, 0.0))

    def on_step(k, state, ref, cmd):
        gait = walker.gait
        swing = gait.swing if gait is not None else None
        return swing is not None and walker.status.time_s - gait.t_phase >= phase * swing.path.duration_s

    run(sim, walker, None, 2.0, on_step=on_step)
    assert walker.gait.swing is not None
    return walker, sim


@pytest.mark.parametrize("pushed_until, moves", [(0.7, True), (0.6, False)])
def test_a_push_late_in_a_swing_still_moves_its_footstep(tiny_biped, crouch, pushed_until, moves):
    config = replace(CONFIG, pushed_retarget_until_phase=pushed_until)
    walker, sim = _to_swing_phase(tiny_biped, crouch, 0.62, config)
    gait = walker.gait
    assert not gait.retargetable(walker.status.time_s)  # past retarget_until_phase (0.6) undisturbed
    before = gait.swing.path.target_position.copy()
    state = _pushed(sim.read_state(), 0.4)
    walker.compute(state)  # the DCM ~0.09 m off the plan through the footstep swung to
    assert np.linalg.norm(walker.status.dcm - walker.status.dcm_ref) > config.cmp_outside_after_m
    for _ in range(6):  # a few cycles more: the footsteps are planned every replan_period_s
        state = state._replace(time_s=state.time_s + 0.002)
        walker.compute(state)
    shift = gait.swing.path.target_position - before
    if moves:  # toward the push (+y), by the step adaptation
        assert shift[1] > 0.01
    else:
        np.testing.assert_allclose(shift, 0.0, atol=1e-12)


def test_the_pushed_retarget_phase_is_checked():
    with pytest.raises(WBCSetupError, match="pushed_retarget_until_phase"):
        WalkingConfig(pushed_retarget_until_phase=1.5)


SOLE = ((-0.05, -0.03), (0.12, -0.03), (0.12, 0.03), (-0.05, 0.03))  # 0.17 m long


def test_a_pushed_step_toward_the_stance_side_crosses_in_front_of_the_stance_foot():
    limits = replace(LIMITS, sole_xy_m=SOLE)
    planner = FootstepPlanner(limits, GaitTiming(0.5, 0.1), ("left", "right"))
    kwargs = dict(pushed_outward_m=1.6 * limits.max_outward_m, cross_gain_m=0.05)
    crossing = StepAdapter(planner, OMEGA, (0.02, 0.005), cross_clearance_m=0.03, **kwargs)
    beside = StepAdapter(planner, OMEGA, (0.02, 0.005), **kwargs)  # no cross-over steps
    stance = Footstep("right", -1, np.array([0.0, 0.0, 0.0]), 0.0)
    nominal = Footstep("left", 1, np.array([0.18, 0.24, 0.0]), 0.0)
    error = [0.0, -0.1]  # pushed toward the stance (right) foot, 0.3 s before the switch
    held = beside.adapt(stance, nominal, error, 0.3, pushed=True)
    assert held.limited and held.footstep.position[1] == pytest.approx(limits.min_width_m, abs=1e-6)
    crossed = crossing.adapt(stance, nominal, error, 0.3, pushed=True)
    # the sole 0.03 m clear ahead of the stance sole (0.17 + 0.03), past the width that kept it beside
    assert crossed.footstep.position[0] == pytest.approx(0.2, abs=1e-6)
    assert crossed.footstep.position[1] < 0.0 < limits.min_width_m
    assert crossed.time_to_switch_s is None
    # not for a step that is not pushed, nor toward the swing side, nor for a small gain
    np.testing.assert_allclose(crossing.adapt(stance, nominal, error, 0.3).footstep.position,
                               beside.adapt(stance, nominal, error, 0.3).footstep.position, atol=1e-12)
    outward = [0.0, 0.1]
    np.testing.assert_allclose(crossing.adapt(stance, nominal, outward, 0.3, pushed=True).footstep.position,
                               beside.adapt(stance, nominal, outward, 0.3, pushed=True).footstep.position,
                               atol=1e-12)
    greedy = StepAdapter(planner, OMEGA, (0.02, 0.005), cross_clearance_m=0.03,
                         pushed_outward_m=1.6 * limits.max_outward_m, cross_gain_m=0.5)
    np.testing.assert_allclose(greedy.adapt(stance, nominal, error, 0.3, pushed=True).footstep.position,
                               held.footstep.position, atol=1e-12)
    with pytest.raises(WBCSetupError, match="cross_clearance_m"):
        StepAdapter(planner, OMEGA, (0.02, 0.005), cross_clearance_m=-0.01)
    with pytest.raises(WBCSetupError, match="cross_over_clearance_m"):
        WalkingConfig(cross_over_clearance_m=-0.01)


def test_a_pushed_step_held_short_forward_is_made_quicker_and_may_reach_further():
    from mbctl.control.wbc.step_adaptation import StepTiming

    planner = FootstepPlanner(LIMITS, GaitTiming(0.5, 0.1), ("left", "right"))
    stance = Footstep("right", -1, np.array([0.0, 0.0, 0.0]), 0.0)
    nominal = Footstep("left", 1, np.array([0.18, 0.24, 0.0]), 0.0)
    error = [0.15, 0.0]  # pushed forward, 0.3 s before the switch: the DCM needs ~0.5 m more, held at 0.36
    timing = StepTiming(np.array([0.03, 0.03]), 0.3, 0.1)
    kwargs = dict(pushed_outward_m=1.6 * LIMITS.max_outward_m)
    sideways_only = StepAdapter(planner, OMEGA, (0.02, 0.005), **kwargs)
    forward_too = StepAdapter(planner, OMEGA, (0.02, 0.005), pushed_timing_along="both", **kwargs)
    backward_only = StepAdapter(planner, OMEGA, (0.02, 0.005), pushed_timing_along="backward", **kwargs)
    held = sideways_only.adapt(stance, nominal, error, 0.3, timing, pushed=True)
    assert held.limited and held.time_to_switch_s is None  # no sideways shortfall: the timing kept
    assert held.footstep.position[0] == pytest.approx(LIMITS.max_forward_m, abs=1e-6)
    quick = forward_too.adapt(stance, nominal, error, 0.3, timing, pushed=True)
    assert 0.1 - 1e-9 <= quick.time_to_switch_s < 0.3  # quicker, not below the floor given
    assert quick.footstep.position[0] <= LIMITS.max_forward_m + 1e-9
    assert backward_only.adapt(stance, nominal, error, 0.3, timing, pushed=True).time_to_switch_s is None
    back = backward_only.adapt(stance, nominal, [-0.25, 0.0], 0.3, timing, pushed=True)  # pushed backward
    assert back.time_to_switch_s is not None and 0.1 - 1e-9 <= back.time_to_switch_s < 0.3
    # a step that is not pushed keeps the sideways-only rule
    assert forward_too.adapt(stance, nominal, error, 0.3, timing).time_to_switch_s is None
    # a pushed forward limit: the pushed step reaches 0.45 m, a walking one the planner's 0.36
    longer = StepAdapter(planner, OMEGA, (0.02, 0.005), pushed_forward_m=0.45, **kwargs)
    assert longer.adapt(stance, nominal, error, 0.3, pushed=True).footstep.position[0] == pytest.approx(0.45)
    assert longer.adapt(stance, nominal, error, 0.3).footstep.position[0] == pytest.approx(0.36, abs=1e-6)
    with pytest.raises(WBCSetupError, match="pushed_forward_m"):
        StepAdapter(planner, OMEGA, (0.02, 0.005), pushed_forward_m=math.inf)
    with pytest.raises(WBCSetupError, match="pushed_timing_along must be one of none, backward, both"):
        StepAdapter(planner, OMEGA, (0.02, 0.005), pushed_timing_along="forward")
    with pytest.raises(WBCSetupError, match="pushed_swing_speed_m_s"):
        WalkingConfig(pushed_swing_speed_m_s=0.0)


def test_a_quick_crossing_step_swings_at_the_quickest_timing_given():
    from mbctl.control.wbc.step_adaptation import StepTiming

    limits = replace(LIMITS, sole_xy_m=SOLE)
    planner = FootstepPlanner(limits, GaitTiming(0.5, 0.1), ("left", "right"))
    kwargs = dict(pushed_outward_m=1.6 * limits.max_outward_m, cross_gain_m=0.05, cross_clearance_m=0.03)
    quick = StepAdapter(planner, OMEGA, (0.02, 0.005), cross_quick=True, **kwargs)
    kept = StepAdapter(planner, OMEGA, (0.02, 0.005), **kwargs)
    stance = Footstep("right", -1, np.array([0.0, 0.0, 0.0]), 0.0)
    nominal = Footstep("left", 1, np.array([0.18, 0.24, 0.0]), 0.0)
    error = [0.0, -0.1]  # pushed toward the stance (right) foot, 0.3 s before the switch
    timing = StepTiming(np.array([0.03, -0.05]), 0.3, 0.12)
    crossed = quick.adapt(stance, nominal, error, 0.3, timing, pushed=True)
    assert crossed.footstep.position[0] == pytest.approx(0.2, abs=1e-6)  # crossed, 0.03 m clear ahead
    assert crossed.footstep.position[1] < 0.0
    assert crossed.time_to_switch_s == pytest.approx(0.12)  # the floor given, not the plan's 0.3
    slow = kept.adapt(stance, nominal, error, 0.3, timing, pushed=True)
    np.testing.assert_allclose(slow.footstep.position, crossed.footstep.position, atol=1e-12)
    assert slow.time_to_switch_s is None
    # a timing given lazily is asked for; without one, or a floor no quicker than now, the timing stays
    assert quick.adapt(stance, nominal, error, 0.3, lambda: timing, pushed=True).time_to_switch_s == \
        pytest.approx(0.12)
    assert quick.adapt(stance, nominal, error, 0.3, None, pushed=True).time_to_switch_s is None
    late = StepTiming(np.array([0.03, -0.05]), 0.3, 0.3)
    assert quick.adapt(stance, nominal, error, 0.3, late, pushed=True).time_to_switch_s is None
    # an uncrossed step (pushed outward) keeps the quicker-step rule alone
    outward = [0.0, 0.1]
    a = quick.adapt(stance, nominal, outward, 0.3, timing, pushed=True)
    b = kept.adapt(stance, nominal, outward, 0.3, timing, pushed=True)
    np.testing.assert_allclose(a.footstep.position, b.footstep.position, atol=1e-12)
    assert a.time_to_switch_s == b.time_to_switch_s
    with pytest.raises(WBCSetupError, match="WalkingConfig.cross_over_quick must be a bool; got 1"):
        WalkingConfig(cross_over_quick=1)
