"""Options of the walking controller (:class:`~mbctl.control.wbc.walking.WalkingController`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from mbctl.control.exceptions import WBCSetupError
from mbctl.control.tasks.base import AccelerationGains
from mbctl.control.wbc.config import WBCConfig
from mbctl.planners.footsteps import GaitTiming


@dataclass(frozen=True)
class WalkingConfig:
    """Options of the walking controller (units in the names).

    Attributes:
        com_height_m: CoM height above the soles while walking [m].
        timing: Single and double support times.
        start_s: Time on both feet before the first swing [s] (the weight shifts, the CoM lowers).
        lift_height_m: Swing foot apex above the ground [m].
        landing_depth_m: The swing path ends this far below the ground [m], so the foot touches
            down on time although it lags its reference a little (it lands at rest on the path).
        step_adaptation: Move the swing footstep to absorb the DCM error outside its tube
            (:mod:`mbctl.control.wbc.step_adaptation`).
        timing_adaptation: With step adaptation, adapt the swing's timing too (a quicker step where a
            limit holds the footstep short; :class:`~mbctl.control.wbc.step_adaptation.StepTiming`); the
            swing path is re-timed to reach its footstep at the new touchdown time.
        min_single_support_s: The quickest swing timing adaptation may ask for [s].
        min_swing_left_s: ... and the least swing time it leaves from now [s].
        timing_weight: The timing's weight w_t in the adaptation QP [m^2].
        timing_threshold_m: The timing is adapted once a limit holds the footstep this far short
            sideways [m].
        max_swing_speed_m_s: A re-timed swing leaves the foot at least its distance to its footstep
            over this [m/s] of horizontal motion (a quicker swing the leg cannot follow lands short).
        pushed_swing_speed_m_s: ... and a pushed step's (the DCM more than ``cmp_outside_after_m`` from its
            plan) over this [m/s].
        pushed_timing_along: A pushed step held ``timing_threshold_m`` short along the heading is made
            quicker too: "none" (sideways shortfalls only, as walking steps), "backward" or "both"
            (:class:`~mbctl.control.wbc.step_adaptation.StepAdapter`).
        dcm_tube_fraction: The DCM tube, as a fraction of the error the CMP feedback can correct
            within the sole: errors beyond it are stepped away.
        dcm_gain_1_s: DCM feedback gain k [1/s] (the error decays as exp(-k t)).
        cmp_margin_m: The desired CMP stays this far inside the support polygon [m] (with
            ``cmp_outside_m`` 0; it also sets the DCM tube).
        cmp_outside_m: The desired CMP may leave the support polygon by up to this [m] instead (it is
            clamped to the polygon grown by it): the QP makes the difference with the centroidal
            angular momentum (the hip strategy), as a pushed robot's DCM passes the sole's edge ...
        cmp_outside_after_m: ... once the DCM is this far [m] from its plan (a push: walking undisturbed
            keeps the CMP ``cmp_margin_m`` inside).
        pushed_double_gain_1_s: The DCM feedback gain [1/s] in double support while the DCM is more than
            ``cmp_outside_after_m`` from its plan (a push): the plan's VRP still moves from the trailing
            foot to the leading one, and at ``dcm_gain_1_s`` the CMP stays near it, behind a DCM that may
            already be over the leading foot; a stiffer law puts it under the DCM, on the leading foot.
        hurried_double_gain_1_s: ... and while it is more than ``hurry_after_m`` from its plan (a
            larger push; walking undisturbed keeps ``pushed_double_gain_1_s``).
        hurry_after_m: In double support with the DCM more than this [m] from its plan, the trailing
            foot is released at once (the next step starts a double support sooner, its force ramps
            overlapping the landing foot's; ``inf``: never).
        pushed_outward_fraction: The step-adaptation QP's outward limit while the DCM is more than
            ``cmp_outside_after_m`` from its plan, as a fraction of the planner's (its reach r beyond
            the nominal width): a step toward a push may spread the feet further than walking does.
        cross_over_clearance_m: A pushed step toward the stance side may cross in front of (or behind)
            the stance foot, its sole this far [m] clear of the stance sole along the heading (``inf``:
            never): the narrowest width keeps the soles apart sideways only, so the swing foot could
            land no nearer than beside the stance foot while the DCM runs away past both.
        cross_over_gain_m: ... when the crossing footstep lands this much [m] nearer where the DCM
            needs it than the uncrossed one (a smaller gain is not worth crossing the legs).
        cross_over_quick: A crossing step swings at the quickest timing the step's timing
            adaptation allows (``min_single_support_s``, ``pushed_swing_speed_m_s``), so the outer
            foot lifts sooner (False: the crossing step keeps the plan's timing).
        preview_steps: Footsteps planned ahead of the swing foot's (>= 1).
        ramp_s: Contact force ramp [s] (<= the double support time).
        swing_horizontal_fraction: The swing foot reaches its footstep's x, y and yaw at this
            fraction of the swing, then descends vertically.
        swing_gains: PD gains of the swing foot's pose task.
        swing_cost: Weight of the swing foot's position [cost]/[m].
        swing_orientation_cost: Weight of the swing foot's orientation [cost]/[rad] (a foot that lands
            tilted touches down on an edge).
        com_cost: Weight of the CoM task [cost]/[m] (the standing set's is 10).
        momentum_cost: Weight of the angular-momentum damping [cost]/[N m] (the standing set's is 0.2).
        torso_cost: Weight of the torso's orientation [cost]/[rad] (the standing task set's is 2): a
            lighter one lets the torso turn on the waist against the legs' yaw reaction.
        torso_yaw_gain: The torso's yaw target is the heading plus this gain [-] times the
            difference of the walker's ``torso_counter_yaw`` joints (e.g. the left hip pitch less the
            right: the torso counter-rotates the legs' swing; 0: the heading).
        arm_swing_gain: Each swinging arm joint's posture target moves by this times its leg joint's
            angle from the start (the controller's ``arm_swing`` pairs; 0: arms held) [-]: the arms
            swing against the legs, so the angular-momentum damping does not fling them.
        height_gains: PD gains of the CoM height (the CoM task's; its horizontal error is zero by
            construction: the horizontal acceleration is the DCM law's).
        touchdown_force_n: A measured normal force above this [N] is a touchdown.
        touchdown_height_m: Without a force measurement: the sole this close to the ground [m].
        early_touchdown_phase: A contact counts as a touchdown from this fraction of the swing on.
        late_descent_m_s: A late foot keeps descending at this speed [m/s] ...
        late_extension_m: ... to at most this far below its footstep [m], where it lands.
        retarget_until_phase: The swing footstep follows the command up to this fraction of the swing.
        pushed_retarget_until_phase: ... and up to this one while the DCM was more than
            ``cmp_outside_after_m`` from its plan the cycle before (a push): a push that comes after
            ``retarget_until_phase`` still moves the footstep (the path itself freezes it
            ``MIN_RETARGET_S`` before its horizontal motion ends, which bounds the swing's acceleration).
        heading_gain_1_s: The footsteps turn by the yaw-rate command plus this gain [1/s] times the
            heading error (the heading reference integrates the yaw-rate command), so slips do not
            accumulate into a turn.
        speed_gain: Gain [-] of the speed loop, per step (0: off): the footsteps' speed is corrected by
            this fraction of the command minus the feet's measured speed over the last step.
        max_speed_correction_m_s: Its largest correction [m/s].
        speed_hold_after_m: A step in which the DCM was more than this from its plan [m] (a push),
            and the recovery's steps after it, correct the speed by their own error alone: the loop
            does not integrate them (``inf``: it integrates every step).
        max_acceleration: How fast the walking speed follows the command: (forward [m/s^2],
            sideways [m/s^2], turning [rad/s^2]) (a step change of command is ramped).
        wbc: The QP's options (its ``ramp_s`` and ``torsion_m`` are replaced by those here).
        moment_feedforward: The CoM's CMP is the DCM law's (the centre of pressure asked for) offset
            by the last cycle's centroidal moment over its normal force, so the swing leg's
            momentum moves the CoM instead of driving the centre of pressure to the sole's edges.
        friction_fraction: The QP plans with this fraction of the soles' friction coefficient
            (0, 1]. Below 1/sqrt 2 its pyramid, a box about the foot's axes, lies
            inside MuJoCo's pyramidal cone (``|f_t1| + |f_t2| <= mu f_n`` about the contact's world-
            aligned tangents) whatever the foot's yaw; the QP's box at full friction reaches
            outside it (its corners at sqrt 2 mu), where the plant's spheres slide.
        torsion_m: Each stance sole's yaw moment stays within this times its normal force [m]
            (``inf``: unbounded; replaces the QP's ``torsion_m``): the swing leg's yaw reaction
            otherwise turns the sole about its toe.
        replan_period_s: The footsteps (the command followed, the swing footstep's retarget and step
            adaptation, the DCM plan through them) are planned every this many seconds, and at
            every contact event; the DCM feedback, the tasks and the QP run every cycle, on the
            plan in force (0: plan every cycle).
    """

    com_height_m: float = 0.64
    timing: GaitTiming = field(default_factory=lambda: GaitTiming(0.5, 0.1))
    start_s: float = 0.6
    lift_height_m: float = 0.07
    landing_depth_m: float = 0.005
    step_adaptation: bool = True
    timing_adaptation: bool = True
    min_single_support_s: float = 0.3
    min_swing_left_s: float = 0.15
    timing_weight: float = 0.001
    timing_threshold_m: float = 0.05
    max_swing_speed_m_s: float = 1.5
    pushed_swing_speed_m_s: float = 1.5
    pushed_timing_along: str = "none"
    dcm_tube_fraction: float = 0.5
    dcm_gain_1_s: float = 3.0
    cmp_margin_m: float = 0.01
    cmp_outside_m: float = 0.02
    cmp_outside_after_m: float = 0.03
    pushed_double_gain_1_s: float = 8.0
    hurried_double_gain_1_s: float = 15.0
    hurry_after_m: float = 0.05
    pushed_outward_fraction: float = 1.6
    cross_over_clearance_m: float = 0.03
    cross_over_gain_m: float = 0.05
    cross_over_quick: bool = True
    preview_steps: int = 3
    ramp_s: float = 0.05
    swing_horizontal_fraction: float = 0.8
    swing_gains: AccelerationGains = AccelerationGains(15.0, 1.0)
    swing_cost: float = 3.0
    swing_orientation_cost: float = 3.0
    com_cost: float = 30.0
    momentum_cost: float = 0.2
    arm_swing_gain: float = 2.0
    torso_cost: float = 2.0
    torso_yaw_gain: float = 0.0
    height_gains: AccelerationGains = AccelerationGains(10.0, 1.0)
    touchdown_force_n: float = 20.0
    touchdown_height_m: float = 0.003
    early_touchdown_phase: float = 0.7
    late_descent_m_s: float = 0.2
    late_extension_m: float = 0.03
    retarget_until_phase: float = 0.6
    pushed_retarget_until_phase: float = 0.7
    heading_gain_1_s: float = 1.0
    speed_gain: float = 0.3
    max_speed_correction_m_s: float = 0.15
    speed_hold_after_m: float = 0.05
    max_acceleration: tuple[float, float, float] = (1.0, 0.5, 1.0)
    wbc: WBCConfig = field(default_factory=WBCConfig)
    moment_feedforward: bool = True
    friction_fraction: float = 0.65
    torsion_m: float = 0.008
    replan_period_s: float = 0.008

    def __post_init__(self) -> None:
        checks = {
            "com_height_m": self.com_height_m > 0, "start_s": self.start_s >= self.timing.double_support_s,
            "lift_height_m": self.lift_height_m >= 0, "landing_depth_m": self.landing_depth_m >= 0,
            "swing_horizontal_fraction": 0 < self.swing_horizontal_fraction <= 1,
            "dcm_gain_1_s": self.dcm_gain_1_s > 0, "cmp_margin_m": self.cmp_margin_m >= 0,
            "cmp_outside_m": self.cmp_outside_m >= 0, "cmp_outside_after_m": self.cmp_outside_after_m >= 0,
            "pushed_double_gain_1_s": self.pushed_double_gain_1_s > 0,
            "hurried_double_gain_1_s": self.hurried_double_gain_1_s > 0,
            "pushed_outward_fraction": self.pushed_outward_fraction > 0,
            "cross_over_gain_m": self.cross_over_gain_m >= 0,
            "friction_fraction": 0 < self.friction_fraction <= 1,
            "dcm_tube_fraction": 0 <= self.dcm_tube_fraction <= 1,
            "min_single_support_s": 0 < self.min_single_support_s <= self.timing.single_support_s,
            "min_swing_left_s": self.min_swing_left_s > 0, "timing_weight": self.timing_weight > 0,
            "timing_threshold_m": self.timing_threshold_m >= 0,
            "max_swing_speed_m_s": self.max_swing_speed_m_s > 0, "preview_steps": self.preview_steps >= 1,
            "pushed_swing_speed_m_s": self.pushed_swing_speed_m_s > 0,
            "ramp_s": 0 < self.ramp_s <= self.timing.double_support_s, "swing_cost": self.swing_cost > 0,
            "swing_orientation_cost": self.swing_orientation_cost > 0,
            "com_cost": self.com_cost > 0, "momentum_cost": self.momentum_cost >= 0,
            "arm_swing_gain": self.arm_swing_gain >= 0, "torso_cost": self.torso_cost > 0,
            "torso_yaw_gain": True,
            "touchdown_force_n": self.touchdown_force_n > 0,
            "touchdown_height_m": self.touchdown_height_m >= 0,
            "early_touchdown_phase": 0 <= self.early_touchdown_phase <= 1,
            "late_descent_m_s": self.late_descent_m_s > 0, "late_extension_m": self.late_extension_m >= 0,
            "retarget_until_phase": 0 <= self.retarget_until_phase <= 1,
            "pushed_retarget_until_phase": 0 <= self.pushed_retarget_until_phase <= 1,
            "heading_gain_1_s": self.heading_gain_1_s >= 0, "speed_gain": 0 <= self.speed_gain <= 1,
            "max_speed_correction_m_s": self.max_speed_correction_m_s >= 0,
            "replan_period_s": self.replan_period_s >= 0,
        }
        for name, ok in checks.items():
            value = getattr(self, name)
            if not (math.isfinite(value) and ok):
                raise WBCSetupError(f"WalkingConfig.{name}={value!r} is out of range")
        if not isinstance(self.cross_over_quick, bool):
            raise WBCSetupError(f"WalkingConfig.cross_over_quick must be a bool; got "
                                f"{self.cross_over_quick!r}")
        if not self.cross_over_clearance_m >= 0:  # (inf allowed: never)
            raise WBCSetupError(f"WalkingConfig.cross_over_clearance_m={self.cross_over_clearance_m!r} is "
                                f"out of range (>= 0 m, or inf)")
        for name in ("hurry_after_m", "torsion_m", "speed_hold_after_m"):  # (inf allowed: never, unbounded)
            value = getattr(self, name)
            if not value > 0:
                raise WBCSetupError(f"WalkingConfig.{name}={value!r} is out of range (> 0 m, or inf)")
        if len(self.max_acceleration) != 3 or not all(math.isfinite(a) and a > 0
                                                      for a in self.max_acceleration):
            raise WBCSetupError(f"WalkingConfig.max_acceleration must be 3 finite values > 0 (m/s^2, m/s^2, "
                                f"rad/s^2); got {self.max_acceleration!r}")


def quick_gait(**changes: Any) -> WalkingConfig:
    """A quicker cadence, for walking at up to about 1 m/s (the default timing caps it near 0.6).

    Steps of 0.28 s single and 0.03 s double support (``ramp_s`` 0.03, no swing quicker than 0.25 s):
    the forward step limit then allows ~1.2 m/s. The swing foot moves horizontally over its whole
    swing and lifts 5 cm (less travel in the shorter swing), and the torso is held lighter (weight 0.5)
    and turned against the legs (``torso_yaw_gain`` 0.6): at that cadence the legs' yaw reaction
    otherwise saturates the shoulders and turns the walk (measured on e.g. the G1, ``docs/api/walking.rst``).

    Args:
        changes: Any other :class:`WalkingConfig` fields (they override the preset's).
    """
    preset: dict[str, Any] = dict(
        timing=GaitTiming(0.28, 0.03), ramp_s=0.03, min_single_support_s=0.25, swing_horizontal_fraction=1.0,
        lift_height_m=0.05, torso_cost=0.5, torso_yaw_gain=0.6)
    return WalkingConfig(**{**preset, **changes})
