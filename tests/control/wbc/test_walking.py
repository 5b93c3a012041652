"""Walking on the whole-body QP, on the biped built in code (conftest.py), in MuJoCo.

Contact switches with force ramps (a foot's weight goes 1 -> 0 before it lifts, 0 -> 1 after it
lands, its QP force with it), the gait's events in order, early and late touchdowns, the command
clamp, the step-adaptation QP and the swing foot task's turning references.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from mbctl.control import run
from mbctl.control.exceptions import WBCSetupError
from mbctl.control.tasks import AccelerationGains, DynamicsState
from mbctl.control.wbc import (
    StepAdapter,
    StepTiming,
    SwingFootTask,
    WalkingConfig,
    WalkingController,
    WBCConfig,
    dcm_tube,
    foot_contact_from_model,
    quick_gait,
)
from mbctl.planners import Footstep, FootstepPlanner, GaitTiming, InvalidPlanningInput, StepLimits
from mbctl.planners.swing import SwingSample
from mbctl.sim import Simulator
from mbctl.sim.monitor import PlantMonitor

FEET = ("l_sole", "r_sole")
#: The biped's CoM stands at 0.517 m; it walks 1.7 cm lower.
CONFIG = WalkingConfig(com_height_m=0.5, wbc=WBCConfig(on_infeasible="damp"))


def _walk(robot, crouch, command, duration_s, config=CONFIG, measured=True, observe=None):
    """Run the walker on the biped in MuJoCo; returns (walker, log, per-cycle records).

    ``observe(walker)``, if given, is called after every cycle.
    """
    q0 = crouch(robot)
    sim = Simulator(robot)
    sim.set_state(q0, np.zeros(robot.nv))
    walker = WalkingController(robot, FEET, "pelvis", "torso", q0, config)
    monitor = PlantMonitor(sim, {f: cs.contact.geoms for f, cs in walker.wbc.contacts.items()}).attach()
    if measured:
        walker.contact_force = lambda f: monitor.contacts[f].normal_n if monitor.contacts else None
    walker.set_command(command)
    rows = []

    def on_step(k, state, ref, cmd):
        sol, s = walker.wbc.solution, walker.status
        rows.append((state.time_s, s.phase, s.event, {f: walker.wbc.contacts[f].weight for f in FEET},
                     {f: float(sol.forces_W[f][:, 2].sum()) for f in FEET},
                     {f: monitor.contacts[f].normal_n for f in FEET}, np.linalg.norm(s.dcm - s.dcm_ref)))
        if observe is not None:
            observe(walker)
        return state.q[2] < 0.4

    log = run(sim, walker, None, duration_s, on_step=on_step)
    return walker, log, rows


def test_the_biped_walks_forward_with_ramped_contact_switches(tiny_biped, crouch):
    walker, log, rows = _walk(tiny_biped, crouch, (0.15, 0.0, 0.0), 3.2)
    assert log.cycles == 1600 and log.q[:, 2].min() > 0.5  # did not fall (pelvis starts at 0.55 m)
    assert walker.wbc.infeasible_at_s is None
    # 0.15 m/s from the first step at 0.6 s: about 0.35 m forward, straight (the pelvis's y averaged over
    # the last stride, 0.6 s, which sways 5 cm to each foot)
    assert 0.25 < log.q[-1, 0] - log.q[0, 0] < 0.5 and abs(log.q[-300:, 1].mean() - log.q[0, 1]) < 0.03
    events = [(r[2].kind, r[2].foot) for r in rows if r[2] is not None]
    assert events[:6] == [("release", "l_sole"), ("lift-off", "l_sole"), ("touchdown", "l_sole"),
                          ("release", "r_sole"), ("lift-off", "r_sole"), ("touchdown", "r_sole")]
    assert walker.steps == sum(kind == "touchdown" for kind, _ in events) >= 4
    # the first release ramps the left foot's weight 1 -> 0 over ramp_s = 0.05 s (25 cycles), its QP
    # force following; the plant's force reaches zero with it, and the foot lifts off at zero
    t_release = next(r[0] for r in rows if r[2] and r[2].kind == "release")
    ramp = [r for r in rows if t_release <= r[0] <= t_release + 0.05 + 1e-9]
    weights = [r[3]["l_sole"] for r in ramp]
    np.testing.assert_allclose(weights, np.maximum(1.0 - 0.04 * np.arange(1, len(ramp) + 1), 0.0), atol=1e-12)
    assert abs(ramp[-1][4]["l_sole"]) < 1e-9 and ramp[-1][5]["l_sole"] < 5.0  # N: the plant's follows
    # the first touchdown ramps it back 0 -> 1 while the QP loads it (one step of the ramp in its cycle)
    t_down = next(r[0] for r in rows if r[2] and r[2].kind == "touchdown")
    after = [r for r in rows if t_down <= r[0] <= t_down + 0.06]
    assert after[0][3]["l_sole"] == pytest.approx(0.04) and after[-1][3]["l_sole"] == 1.0
    # when the right foot lifts off, the left carries the weight (23.3 kg), in the QP and in the plant
    lift = next(r for r in rows if r[2] and r[2].kind == "lift-off" and r[2].foot == "r_sole")
    mg = tiny_biped.mj_model.body_subtreemass[1] * 9.81
    assert lift[4]["l_sole"] == pytest.approx(mg, rel=0.1) and lift[5]["l_sole"] == pytest.approx(mg, rel=0.1)
    # the DCM stays within 3 cm of its plan (measured 2.15 cm at most, 1.0 cm RMS: the CoM carries the
    # swing leg's moment, see the next test; 0.8 cm and 0.4 cm without the moment feedforward)
    assert max(r[6] for r in rows) < 0.03


def _cop_errors(robot, crouch, config) -> np.ndarray:
    """Each single-support cycle's |QP centre of pressure - the one the DCM law asked for| [m]."""
    errors = []

    def observe(walker):
        s, sol = walker.status, walker.wbc.solution
        if s.phase == "single":
            F, P = sol.forces_W[s.stance], sol.points_W[s.stance]
            errors.append(np.linalg.norm(F[:, 2] @ P[:, :2] / F[:, 2].sum() - s.cmp_clamped))

    _walk(robot, crouch, (0.15, 0.0, 0.0), 3.2, config, observe=observe)
    return np.array(errors)


def test_the_moment_feedforward_puts_the_centre_of_pressure_where_the_dcm_law_asks(tiny_biped, crouch):
    """Without it the swing leg's moment moves the QP's CoP 36 mm (median) off the DCM law's CMP, with
    it 2 mm: the CoM's CMP is offset by the last cycle's centroidal moment over the normal force."""
    on = _cop_errors(tiny_biped, crouch, CONFIG)
    off = _cop_errors(tiny_biped, crouch, replace(CONFIG, moment_feedforward=False))
    assert np.median(on) < 0.005 < 0.02 < np.median(off)
    assert np.percentile(on, 95) < 0.5 * np.percentile(off, 95)


def test_the_soles_yaw_moment_and_friction_stay_within_the_walkers_margins(tiny_biped, crouch):
    """Each loaded sole's QP yaw moment about its centre is within torsion_m f_z, each point's
    tangential force within friction_fraction mu / sqrt 2 f_z per axis; unbounded, the moment exceeds it."""
    mu = {f: foot_contact_from_model(tiny_biped, f).mu for f in FEET}

    def worst(config):
        out = [0.0, 0.0]

        def observe(walker):
            sol = walker.wbc.solution
            for f, F in sol.forces_F.items():
                if F[:, 2].sum() > 1.0:
                    r = sol.points_F[f] - sol.points_F[f].mean(axis=0)
                    moment = np.sum(r[:, 0] * F[:, 1] - r[:, 1] * F[:, 0])
                    out[0] = max(out[0], abs(moment) / F[:, 2].sum())
                    out[1] = max(out[1], float(np.max(np.abs(F[:, :2]) / (mu[f] * F[:, 2:] + 1e-12))))

        _walk(tiny_biped, crouch, (0.15, 0.0, 0.1), 2.4, config, observe=observe)
        return out

    assert CONFIG.torsion_m == 0.008 and CONFIG.friction_fraction == 0.65
    torsion, friction = worst(CONFIG)
    assert torsion <= 0.008 + 1e-6 and friction <= 0.65 / math.sqrt(2.0) + 1e-6
    torsion, friction = worst(replace(CONFIG, torsion_m=1e3, friction_fraction=1.0))
    assert torsion > 0.015 and friction > 0.65 / math.sqrt(2.0) + 0.01


def test_early_and_late_touchdowns(tiny_biped, crouch):
    # without a force sensor the sole's height detects the touchdowns
    walker, _, _ = _walk(tiny_biped, crouch, (0.1, 0.0, 0.0), 2.0, measured=False)
    assert walker.steps >= 2 and sum(walker.gait.touchdowns.values()) == walker.steps
    # a contact sensor that always reads 100 N: the touchdown comes at the early phase (70 % of 0.5 s)
    q0 = crouch(tiny_biped)
    sim = Simulator(tiny_biped)
    sim.set_state(q0, np.zeros(tiny_biped.nv))
    early = WalkingController(tiny_biped, FEET, "pelvis", "torso", q0, CONFIG, contact_force=lambda f: 100.0)
    events = []
    run(sim, early, None, 1.5, on_step=lambda k, s, r, c: events.append(early.status.event) and False)
    lift = next(e for e in events if e and e.kind == "lift-off")
    down = next(e for e in events if e and e.kind == "touchdown")
    assert down.timing == "early"
    assert down.time_s - lift.time_s == pytest.approx(0.7 * 0.5, abs=0.0021)
    # a sensor that never reads contact and a detector that never fires: the foot descends 0.2 m/s
    # past its planned touchdown and is put down 0.03 m lower, 0.15 s late ("forced")
    late_config = WalkingConfig(com_height_m=0.5, touchdown_height_m=0.0, landing_depth_m=0.0,
                                wbc=WBCConfig(on_infeasible="damp"))
    late = WalkingController(tiny_biped, FEET, "pelvis", "torso", q0, late_config,
                             contact_force=lambda f: 0.0)
    sim = Simulator(tiny_biped)
    sim.set_state(q0, np.zeros(tiny_biped.nv))
    events = []
    run(sim, late, None, 1.6, on_step=lambda k, s, r, c: events.append(late.status.event) and False)
    lift = next(e for e in events if e and e.kind == "lift-off")
    down = next(e for e in events if e and e.kind == "touchdown")
    assert down.timing == "forced" and late.gait.touchdowns["forced"] == 1
    assert down.time_s - lift.time_s == pytest.approx(0.5 + 0.03 / 0.2, abs=0.0021)


def test_the_command_is_clamped_and_reported(tiny_biped, crouch):
    walker = WalkingController(tiny_biped, FEET, "pelvis", "torso", crouch(tiny_biped), CONFIG)
    clamp = walker.set_command((5.0, 0.0, 0.0))
    assert clamp.limited_by == ("forward step",)
    assert clamp.applied.vx_m_s == pytest.approx(walker.limits.max_forward_m / 0.6, rel=1e-12)
    assert walker.command is clamp
    with pytest.raises(InvalidPlanningInput, match="finite"):
        walker.set_command((math.inf, 0.0, 0.0))
    with pytest.raises(WBCSetupError, match="two feet"):
        WalkingController(tiny_biped, ["l_sole"], "pelvis", "torso", crouch(tiny_biped), CONFIG)
    with pytest.raises(WBCSetupError, match="ramp_s"):
        WalkingConfig(ramp_s=0.2)
    with pytest.raises(WBCSetupError, match=r"WalkingConfig.friction_fraction=1.2 is out of range"):
        WalkingConfig(friction_fraction=1.2)
    with pytest.raises(WBCSetupError, match=r"WalkingConfig.torsion_m=0.0 is out of range"):
        WalkingConfig(torsion_m=0.0)
    with pytest.raises(WBCSetupError, match=r"WalkingConfig.replan_period_s=-0.002 is out of range"):
        WalkingConfig(replan_period_s=-0.002)
    with pytest.raises(WBCSetupError, match="arm_swing or torso_counter_yaw names joints the model does not "
                                            "have: l_shoulder"):
        WalkingController(tiny_biped, FEET, "pelvis", "torso", crouch(tiny_biped), CONFIG,
                          arm_swing={"l_shoulder": "r_hip_pitch"})


LIMITS = StepLimits(0.36, 0.2, 0.2, 0.24, 0.1, 0.6)
SOLE = np.array([[-0.05, 0.025, -0.035], [-0.05, -0.025, -0.035], [0.12, 0.03, -0.035],
                 [0.12, -0.03, -0.035]])
OMEGA = math.sqrt(9.81 / 0.64)


def _adapter():
    tube = dcm_tube(SOLE, 0.01, 3.0, OMEGA, 0.5)
    return StepAdapter(FootstepPlanner(LIMITS, GaitTiming(0.5, 0.1), ("left", "right")), OMEGA, tube), tube


def test_the_dcm_tube_is_what_the_cmp_corrects_in_the_sole():
    _, tube = _adapter()
    # sole centre (0.035, 0): 0.085 m to the toe and heel; sideways the sole is 2.75 cm wide there (2.5 at
    # the heel, 3 at the toe); less the 1 cm margin, over 1 + k / omega, half of it
    np.testing.assert_allclose(tube, 0.5 * np.array([0.075, 0.0175]) / (1 + 3.0 / OMEGA), rtol=1e-12)


def test_step_adaptation_moves_the_footstep_by_the_error_outside_the_tube():
    adapter, tube = _adapter()
    stance = Footstep("right", -1, np.array([1.0, 0.0, 0.0]), math.pi / 2)  # heading +y: forward is +y
    nominal = Footstep("left", 1, np.array([0.76, 0.2, 0.0]), math.pi / 2)  # 0.2 ahead, 0.24 to its left
    inside = adapter.adapt(stance, nominal, [0.0, 0.5 * tube[0]], 0.3)
    assert not inside.outside_tube and inside.footstep is nominal and inside.solve_time_s == 0.0
    # 1 cm forward beyond the tube, 0.3 s before the switch: the footstep goes exp(omega 0.3) cm further
    moved = adapter.adapt(stance, nominal, [0.0, tube[0] + 0.01], 0.3)
    assert moved.outside_tube and not moved.limited
    expected = 0.01 * math.exp(OMEGA * 0.3) / (1 + adapter.nominal_weight)
    np.testing.assert_allclose(moved.shift_m, [0.0, expected], atol=1e-9)
    assert moved.footstep.yaw_rad == nominal.yaw_rad
    # an error pushing the foot across the stance foot: held at the narrowest width, reported
    crossing = adapter.adapt(stance, nominal, [0.2, 0.0], 0.3)  # +x is to the stance's right
    assert crossing.limited
    d = crossing.footstep.position - stance.position
    assert -d[0] == pytest.approx(LIMITS.min_width_m, abs=1e-9)  # the width toward its side (-x here)


def test_a_footstep_held_short_sideways_lands_sooner_with_timing_adaptation():
    adapter, tube = _adapter()
    stance = Footstep("right", -1, np.array([0.0, 0.0, 0.0]), 0.0)
    nominal = Footstep("left", 1, np.array([0.1, 0.24, 0.0]), 0.0)
    dcm_ref = np.array([0.05, 0.05])
    error = [0.0, 0.08]  # a push to the swing side, 0.4 s before the switch: beyond the outward limit
    timing = StepTiming(dcm_ref, 0.4, 0.15)
    fixed = adapter.adapt(stance, nominal, error, 0.4)
    timed = adapter.adapt(stance, nominal, error, 0.4, timing)
    assert fixed.limited and fixed.time_to_switch_s is None
    assert timed.time_to_switch_s is not None and 0.15 - 1e-9 <= timed.time_to_switch_s < 0.4 - 0.05

    def shortfall(adaptation, time_to_switch_s):  # the DCM at the switch against the plan's offset
        r_s, e_out = np.array([0.035, 0.0]), np.array([0.0, error[1] - tube[1]])
        xi_switch = r_s + math.exp(OMEGA * time_to_switch_s) * (dcm_ref + e_out - r_s)
        b_nom = r_s + math.exp(OMEGA * 0.4) * (dcm_ref - r_s) - (nominal.position[:2] + r_s)
        return np.linalg.norm(xi_switch - (adaptation.footstep.position[:2] + r_s) - b_nom)

    adapter.sole_centre_xy = (0.035, 0.0)
    timed = adapter.adapt(stance, nominal, error, 0.4, timing)
    assert shortfall(timed, timed.time_to_switch_s) < 0.5 * shortfall(fixed, 0.4)
    # the footstep stays within its limits
    assert timed.footstep.position[1] <= LIMITS.nominal_width_m + LIMITS.max_outward_m + 1e-9
    # not held short: the timing stays the plan's
    moved = adapter.adapt(stance, nominal, [tube[0] + 0.01, 0.0], 0.4, timing)
    assert moved.outside_tube and not moved.limited and moved.time_to_switch_s is None


def test_the_swing_task_feeds_the_yaw_rate_and_acceleration_forward(tiny_biped, crouch):
    model = tiny_biped.pin_model
    state = DynamicsState(model, crouch(tiny_biped), np.zeros(model.nv))
    task = SwingFootTask("l_sole", model, 3.0, AccelerationGains(15.0, 1.0))
    X = state.frame_pose(task.frame_id)
    yaw = math.atan2(X.rotation[1, 0], X.rotation[0, 0])
    task.set_swing_target(SwingSample(X.translation.copy(), np.zeros(3), np.zeros(3), yaw, 0.8, 0.5, 2.0))
    J, _ = task.jacobian_and_drift(state)
    a = task.desired_acceleration(state, J)
    # at the target, at rest: the angular part is R_FW (0, 0, alpha + kd rate), kd = 2 zeta omega = 30
    R_FW = X.rotation.T
    np.testing.assert_allclose(a[3:], R_FW[:, 2] * (2.0 + 30.0 * 0.8), atol=1e-9)
    np.testing.assert_allclose(a[:3], 0.0, atol=1e-9)
    assert task.yaw_rate_rad_s == 0.8 and task.yaw_acceleration_rad_s2 == 2.0
    # the stack's terms (a_des + kd J v - Jdot v, at rest a_des - Jdot v): the same law
    assert task.stacked_acceleration
    J_t, r_t = np.zeros_like(J), np.zeros(6)
    task.write_acceleration_terms(state, J_t, r_t)
    np.testing.assert_allclose(r_t, a - task.jacobian_and_drift(state)[1], atol=1e-9)


@pytest.mark.parametrize(("replan_period_s", "plans"), [(0.0, 76), (0.008, 20)])
def test_a_plan_is_reused_while_its_footsteps_and_command_stay(tiny_biped, crouch, monkeypatch,
                                                               replan_period_s, plans):
    # standing before the first swing: the command ramps to 0.15 m/s at 1 m/s^2 (0.15 s, 75 cycles of
    # 2 ms), then the footsteps, the VRPs and the command stay and so does the plan. While it ramps, a
    # plan is made at every footstep planning: every cycle (0 s), or every 4th (0.008 s: at 0, 0.008,
    # ..., 0.152 s, where the command has stayed at 0.15 m/s)
    import mbctl.control.wbc._walking_plan as walking_plan

    built = []

    class Counting(walking_plan.DcmPlan):
        def _build(self, omega, vrps, switches, *args):
            built.append(switches[0])  # the first switch [s]
            super()._build(omega, vrps, switches, *args)

    monkeypatch.setattr(walking_plan, "DcmPlan", Counting)
    config = replace(CONFIG, replan_period_s=replan_period_s)
    walker, log, rows = _walk(tiny_biped, crouch, (0.15, 0.0, 0.0), 0.5, config)
    assert log.cycles == 250 and all(r[1] == "start" for r in rows)
    assert len(built) == plans and walker.velocity.vx_m_s == 0.15
    # the plan kept is the one a fresh build gives: the same reference at the last cycle
    plan, _ = walker.plans.plan(walker.gait, rows[-1][0], walker._steer)
    again = walking_plan.DcmPlan.__mro__[1](plan.omega, plan.vrps, plan.switch_times_s, plan.double_support_s,
                                       plan.alpha, plan._initial)
    for t in (rows[-1][0], 0.55, 0.7, 1.2):
        np.testing.assert_array_equal(plan.at(t).xi, again.at(t).xi)


def test_footsteps_are_planned_every_replan_period_and_at_every_contact_event(tiny_biped, crouch):
    # the command followed and the swing footstep (retarget, step adaptation) are updated every
    # replan_period_s (here 5 cycles) and at each release, lift-off and touchdown, never in between;
    # the DCM law and the QP still run every cycle, on the plan in force, and the biped walks as far
    config = replace(CONFIG, replan_period_s=0.01)
    retargets, events, adaptations = [], [], []

    def observe(walker):
        status = walker.status
        if status.event is not None:
            events.append(status.time_s)
        if status.adaptation is not None and (not adaptations or status.adaptation is not adaptations[-1]):
            adaptations.append(status.adaptation)  # a new one: the swing footstep was planned this cycle
            retargets.append(status.time_s)

    walker, log, rows = _walk(tiny_biped, crouch, (0.15, 0.0, 0.0), 3.2, config, observe=observe)
    assert log.q[:, 2].min() > 0.5 and walker.wbc.infeasible_at_s is None
    assert 0.25 < log.q[-1, 0] - log.q[0, 0] < 0.5
    gaps = np.diff(retargets)
    off_schedule = [t for t, gap in zip(retargets[1:], gaps, strict=True)
                    if gap < 0.01 - 1e-9 and not any(abs(t - e) < 1e-9 for e in events)]
    assert off_schedule == [] and len(retargets) > 100
    # within a swing's retargeting window (0.6 of 0.5 s) it is planned every 5th cycle
    assert np.median(gaps) == pytest.approx(0.01)


def test_the_torso_turns_against_the_legs_by_its_yaw_gain_and_is_held_lighter(tiny_biped, crouch):
    """torso_yaw_gain: the torso's yaw target is the heading plus the gain times q_a - q_b; the pelvis's
    stays the heading; torso_cost replaces the standing task set's torso weight."""
    config = replace(CONFIG, torso_yaw_gain=0.6, torso_cost=0.5)
    q0 = crouch(tiny_biped)
    walker = WalkingController(tiny_biped, FEET, "pelvis", "torso", q0, config,
                               torso_counter_yaw=("l_hip_pitch", "r_hip_pitch"))
    np.testing.assert_array_equal(walker.standing.torso.cost, 0.5)
    m = walker.model
    a, b = (m.joints[m.getJointId(j)].idx_q for j in ("l_hip_pitch", "r_hip_pitch"))
    q = q0.copy()
    q[a] += 0.2  # the left thigh 0.2 rad back of the right's: the torso turns 0.12 rad
    sim = Simulator(tiny_biped)
    sim.set_state(q, np.zeros(tiny_biped.nv))
    state = sim.read_state()
    walker.compute(state)
    heading = walker.gait.heading(state.time_s)

    def yaw(task):
        R = task.transform_target_to_world.rotation
        return math.atan2(R[1, 0], R[0, 0])

    assert yaw(walker.standing.torso) == pytest.approx(heading + 0.6 * (state.q[a] - state.q[b]), abs=1e-12)
    assert yaw(walker.standing.base) == pytest.approx(heading, abs=1e-12)
    plain = WalkingController(tiny_biped, FEET, "pelvis", "torso", q0, CONFIG)
    plain.compute(state)
    assert yaw(plain.standing.torso) == pytest.approx(plain.gait.heading(state.time_s), abs=1e-12)
    np.testing.assert_array_equal(plain.standing.torso.cost, 2.0)
    with pytest.raises(WBCSetupError, match="torso_counter_yaw names joints the model does not have: l_hip"):
        WalkingController(tiny_biped, FEET, "pelvis", "torso", q0, config,
                          torso_counter_yaw=("l_hip", "r_knee"))
    with pytest.raises(WBCSetupError, match=r"WalkingConfig.torso_cost=0.0 is out of range"):
        WalkingConfig(torso_cost=0.0)
    with pytest.raises(WBCSetupError, match=r"WalkingConfig.torso_yaw_gain=nan is out of range"):
        WalkingConfig(torso_yaw_gain=math.nan)


def test_the_quick_gait_steps_quicker_and_takes_overrides():
    quick = quick_gait()
    assert quick.timing == GaitTiming(0.28, 0.03) and quick.ramp_s == 0.03
    assert quick.min_single_support_s == 0.25 and quick.swing_horizontal_fraction == 1.0
    assert (quick.lift_height_m, quick.torso_cost, quick.torso_yaw_gain) == (0.05, 0.5, 0.6)
    assert quick_gait(com_height_m=0.5).com_height_m == 0.5 and quick_gait(ramp_s=0.02).ramp_s == 0.02
    with pytest.raises(WBCSetupError, match=r"WalkingConfig.ramp_s=0.05 is out of range"):
        quick_gait(ramp_s=0.05)  # above its 0.03 s double support
