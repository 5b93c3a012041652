"""The G1's excitation on its feet: whole-body control through squat, sway, upper-body motion, steps.

The Menagerie G1 stands on its feet in torque mode under the whole-body controller
(:func:`mbctl.jobs.g1_wbc.g1_whole_body`, the nominal model or ``--controller-model``), whose task
references move it:

* the waist and both arms follow a Fourier-series excitation optimised for the condition number
  of the upper body's regressor (pelvis fixed in the design) within joint ranges that keep the
  arms away from the body, shrunk until the sampled motion clears every self-collision with a
  margin (the posture task carries it; the torso orientation task follows the waist);
* the CoM squats and sways at incommensurate frequencies inside the support polygon, and the
  pelvis rocks in roll and pitch;
* unless the run is short, each foot in turn is unloaded (force ramp), lifted straight up and put
  back where it left the floor (the posture task, its leg solved each cycle by the chain IK of
  :class:`mbctl.control.ik.ChainIK` on a pose task of the foot, to a tolerance; solves that do not
  converge are counted in the report), and reloaded, with the CoM over the other foot.

It runs in the control loop every job uses (``control.loop.run``, the controller
``Scheduled``). Every cycle is a row of the identification log, measured by the plant
(:class:`~mbctl.sim.monitor.PlantMonitor`): the actuators' torques, the feet's contact flags and
wrenches and the count of contacts elsewhere. A fall by the G1's one rule
(:data:`~mbctl.robots.g1.G1_FALL`: pelvis low, or a body other than a foot on the floor) ends the
run with exit 1, every row kept.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from mbctl.control.loop import run
from mbctl.control.wbc import Scheduled, WBCConfig
from mbctl.jobs.excite import DEFAULT_DURATION_S, SAME_TRAJECTORY, ExciteParams, log_section
from mbctl.jobs.excite_g1_balance import BalanceWatch, SupportPolygon
from mbctl.jobs.excite_g1_log import ExciteLog, plot
from mbctl.jobs.excite_g1_schedule import (
    COM_AMPLITUDE_M,
    COM_FREQUENCY_HZ,
    PELVIS_AMPLITUDE_RAD,
    PELVIS_FREQUENCY_HZ,
    Schedule,
    step_starts,
)
from mbctl.jobs.excite_g1_steps import STEP_TIMES_S
from mbctl.jobs.g1_wbc import g1_whole_body
from mbctl.jobs.ident_log import CSV_NAME, SECTION, header
from mbctl.jobs.model_options import Models, build_models, models_line
from mbctl.jobs.plant import Plant, dry_run, plant_lines, prepare_plant, report_plant
from mbctl.jobs.runner import Outcome, RunContext, Work
from mbctl.jobs.truth import truth_com
from mbctl.planners.excitation import ExcitationDesign, ExcitationLimits, design_excitation
from mbctl.planners.fourier import FourierTrajectory
from mbctl.robots.collision import SelfClearance
from mbctl.robots.edits import position_to_motor, weld_base
from mbctl.robots.g1 import (
    FEET,
    FOOT_BODIES,
    G1_FALL,
    KEYFRAME,
    TORSO,
    crouched_start,
    joint_role,
    limb_of,
    with_palm_sites,
)
from mbctl.robots.identification.threads import single_threaded_blas
from mbctl.robots.model_pair import Robot
from mbctl.sim.monitor import PlantMonitor

#: Range [rad] of each upper-body joint around the keyframe, (below, above); the shoulder roll
#: only opens the arms outward and the elbow stays bent, away from the body.
UPPER_RANGES_RAD = {
    "waist_yaw": (0.35, 0.35), "waist_roll": (0.15, 0.15), "waist_pitch": (0.2, 0.2),
    "shoulder_pitch": (0.6, 0.5), "shoulder_roll": (0.1, 0.7), "shoulder_yaw": (0.5, 0.5),
    "elbow": (0.6, 0.5), "wrist_roll": (0.5, 0.5), "wrist_pitch": (0.5, 0.5), "wrist_yaw": (0.5, 0.5),
}
#: The arms open outward by this shoulder roll [rad] before the upper body's excitation starts
#: (the keyframe's hands hang beside the thighs).
ARM_OPEN_RAD = 0.35
#: Clearance [m] the designed upper-body motion keeps between the robot's own geoms.
CLEARANCE_M = 0.03
def upper_joints(robot: Robot) -> tuple[str, ...]:
    """The waist and arm joints (the upper body the Fourier excitation moves), model order."""
    return tuple(j for j in robot.joints if joint_role(j) in UPPER_RANGES_RAD)


def _limits(robot: Robot, joints: tuple[str, ...], q0: np.ndarray, torque_fraction: float = 0.4
            ) -> ExcitationLimits:
    base = ExcitationLimits.from_robot(robot, joints, q0, range_rad=1.0, torque_fraction=torque_fraction)
    lo, hi = base.q_min.copy(), base.q_max.copy()
    for k, j in enumerate(joints):
        role = joint_role(j)
        below, above = UPPER_RANGES_RAD[role]
        if limb_of(j) == "right arm" and role == "shoulder_roll":
            below, above = above, below  # the right arm opens toward negative roll
        value = q0[robot.joint(j).idx_q]
        lo[k], hi[k] = max(lo[k], value - below), min(hi[k], value + above)
    return ExcitationLimits(lo, hi, np.full(len(joints), 2.0), base.tau_max)


def _mirror(traj: FourierTrajectory, names: tuple[str, ...], q_start: np.ndarray) -> FourierTrajectory:
    """The left arm's excitation on the right arm, mirrored in the sagittal plane (roll and yaw negated).

    The arms swing symmetrically, so their sideways pull on the CoM cancels.
    """
    sign = np.array([-1.0 if ("roll" in n or "yaw" in n) else 1.0 for n in traj.names])[:, None]
    return FourierTrajectory(names, q_start, traj.period_s, traj.a * sign, traj.b * sign)


def design_upper_body(nominal: Robot, q_start: np.ndarray, params: ExciteParams
                      ) -> tuple[FourierTrajectory, list[ExcitationDesign], float]:
    """The upper body's Fourier excitation, designed on the welded nominal G1, clear of itself.

    The waist is optimised for the waist and torso parameters, the left arm for its links', and
    the right arm mirrors the left (so the arms' sideways pulls cancel); all three start at rest
    with the arms opened by :data:`ARM_OPEN_RAD`. The amplitude is shrunk until the sampled motion
    keeps :data:`CLEARANCE_M` between geoms that were not that close at the start.

    Returns:
        The trajectory, the two designs (waist, arm), and the amplitude's shrink factor (1: none).
    """
    welded = weld_base(nominal, KEYFRAME)
    q_w = q_start[7:].copy()  # the welded model's q is the floating one's without the base
    for side, sign in (("left", 1.0), ("right", -1.0)):
        q_w[welded.joint(f"{side}_shoulder_roll_joint").idx_q] += sign * ARM_OPEN_RAD
    period = params.period
    harmonics = min(params.harmonics, 3)
    designs = []
    for part in ("waist", "left"):
        joints = tuple(j for j in upper_joints(welded) if j.startswith(part))
        bodies = [b for b in welded.bodies if b.startswith(part) or (part == "waist" and b == TORSO)]
        designs.append(design_excitation(welded, joints, q_w, limits=_limits(welded, joints, q_w),
                                         period_s=period, harmonics=harmonics, n_samples=40, bodies=bodies,
                                         seed=params.seed, max_iterations=20,
                                         # the three parts' motion together is kept clear below
                                         self_clearance=False))
    waist, left = designs[0].trajectory, designs[1].trajectory
    right_names = tuple(n.replace("left_", "right_", 1) for n in left.names)
    right_q0 = np.array([q_w[welded.joint(n).idx_q] for n in right_names])
    right = _mirror(left, right_names, right_q0)
    check = SelfClearance(welded, CLEARANCE_M, q_w)
    t = np.linspace(0.0, period, 120, endpoint=False)
    scale = 1.0
    for _ in range(30):
        parts = [FourierTrajectory(p.names, p.q_start, p.period_s, p.a * scale, p.b * scale)
                 for p in (waist, left, right)]
        qs = np.tile(q_w, (len(t), 1))
        for p in parts:
            qs[:, [welded.joint(n).idx_q for n in p.names]] = p.sample(t)[0]
        if not any(check.touches(q) for q in qs):
            break
        scale *= 0.85
    names = tuple(n for p in parts for n in p.names)
    combined = FourierTrajectory(names, np.concatenate([p.q_start for p in parts]), period,
                                 np.vstack([p.a for p in parts]), np.vstack([p.b for p in parts]))
    return combined, designs, scale


def prepare_g1(params: ExciteParams, loaded: Robot) -> Work:
    """The G1 in torque mode with palm sites; the upper body's excitation designed; over DDS, connected.

    Raises:
        NoRobotError, JointOutOfLimits, ChannelError: Over DDS, before anything is written (exit 2).
    """
    def edit(r: Robot) -> Robot:
        return position_to_motor(with_palm_sites(r))

    nominal = edit(loaded)  # the design's model: the robot's own, whatever the controller uses
    models = build_models(nominal, params.models, edit)
    q_start = crouched_start(nominal)
    upper, designs, shrink = design_upper_body(nominal, q_start, params)
    duration = params.duration or DEFAULT_DURATION_S
    # over DDS this connects now: no robot, or one outside its limits, is bad input (exit 2)
    plant = prepare_plant(params.plant, models.plant, KEYFRAME, start_q=q_start, contact_forces=True)

    def work(ctx: RunContext) -> Outcome:
        with plant(ctx) as p, single_threaded_blas():  # the whole-body QP's matrices are small
            ctx.sections["plant"] = models.section()
            if p.options.dry_run:
                return dry_run(ctx, p, duration)
            return _run(ctx, params, nominal, models, p, upper, (designs, shrink), duration)

    return work


def _run(ctx: RunContext, params: ExciteParams, nominal: Robot, models: Models, p: Plant,
         upper: FourierTrajectory, design: tuple[list[ExcitationDesign], float], duration: float) -> Outcome:
    iface, sim = p.interface, p.sim  # sim: the in-process plant (None over DDS)
    wb = g1_whole_body(models.plant, models.controller_model, WBCConfig(friction_feedforward=True))
    state = iface.read_state()
    wb.hold(state)
    steps = step_starts(duration)
    watch = BalanceWatch()
    schedule = Schedule(wb, models.plant, models.controller_model, upper, np.array(state.q), steps, watch)
    bodies, joints = FOOT_BODIES, wb.controller.joints.joints  # joints: the commands' order
    monitor = None
    if sim is not None:  # the plant measures what the log records: torques, wrenches, contacts, falls
        monitor = PlantMonitor(sim, fall_rule=G1_FALL.reason, joints=joints, wrench_bodies=bodies,
                               count_elsewhere=True).attach()
    soles = {f: cs.contact.points_F for f, cs in wb.controller.contacts.items()}
    polygon = SupportPolygon(models.controller_model, soles, dict(zip(FEET, bodies, strict=True)))
    dt = iface.control_period_s
    ctx.sections[SECTION] = log_section(params, nominal, joints, bodies, dt,
                                        _excitation(upper, design, steps), measured=monitor is not None)
    csv = ctx.open_csv(header(models.plant, joints, bodies, measured=monitor is not None), CSV_NAME)
    log = ExciteLog(csv, wb, lambda: schedule.com_ref, polygon, watch, monitor, ctx.progress.advance,
                    p.estimator)
    ctx.progress.start(max(1, int(round(duration / dt))), "excite g1")
    # the schedule moves the task targets from the measured state (the swing leg's IK starts at the
    # base's pose): the state it gets is the one the loop just read (no time passes between)
    run_log = run(iface, Scheduled(wb.controller, schedule.update), None, duration, on_step=log.on_step)
    truth_fell = report_plant(ctx, p, run_log, G1_FALL.base_min_z_m)
    fell = None if log.fall_reason is None else f"{log.fall_reason} at t={log.fall_time_s:.2f} s"
    if truth_fell:
        fell = fell or "the bridge's truth log: the pelvis went below the fall height"
    com, com_from = np.asarray(log.com), "the plant" if monitor is not None else "the estimated state"
    if p.options.truth is not None and len(log.t):
        com, com_from = truth_com(p.options.truth, run_log.tick[:len(log.t)], run_log.q[:1]), "truth"
    com_err = com - np.asarray(log.com_ref)
    checked = monitor is not None or truth_fell is not None  # over DDS without a truth log: unchecked
    ctx.values.update({"duration_s": log.t[-1] - log.t[0] + dt if log.t else 0.0, "rows": len(log.t),
                       "fell": True if fell else (False if checked else None), "fall_reason": fell,
                       "com_error_rms_m": float(np.sqrt(np.mean(np.sum(com_err**2, 1)))),
                       "com_error_from": com_from,
                       "waist_condition_number": design[0][0].condition_number,
                       "arm_condition_number": design[0][1].condition_number,
                       "samples_with_other_contacts": log.rows_with_other_contacts if monitor else None,
                       "swing_leg_ik": schedule.legs.section(), **watch.section()})
    plot(ctx, log, bodies, joints, fell, measured=monitor is not None)
    return _outcome(ctx, models, schedule, log, design, fell)


def _excitation(upper: FourierTrajectory, design: tuple[list[ExcitationDesign], float],
                steps: list[tuple[str, float]]) -> dict[str, Any]:
    """The ``excitation`` entry of the log's section."""
    designs, shrink = design
    return {
        "kind": "whole-body control on the feet: upper-body Fourier excitation, CoM squat and sway, pelvis "
                "roll and pitch, steps; scaled down or stopped by the balance watch",
        "upper_body": {"joints": list(upper.names), "period_s": upper.period_s, "harmonics": upper.harmonics,
                       "condition_number": {"waist": designs[0].condition_number,
                                            "left_arm": designs[1].condition_number},
                       "initial_condition_number": {"waist": designs[0].initial_condition_number,
                                                    "left_arm": designs[1].initial_condition_number},
                       "right_arm": "the left arm's motion mirrored (roll and yaw negated)",
                       "amplitude_scale_for_clearance": shrink, "clearance_m": CLEARANCE_M,
                       "arms_opened_rad": ARM_OPEN_RAD},
        "com": {"amplitude_m": COM_AMPLITUDE_M, "frequency_hz": COM_FREQUENCY_HZ},
        "pelvis": {"amplitude_rad": PELVIS_AMPLITUDE_RAD, "frequency_hz": PELVIS_FREQUENCY_HZ},
        "steps": [{"foot": f, "start_s": t0, "phases_s": STEP_TIMES_S} for f, t0 in steps],
        "swing_leg": "a foot pose task in the QP while the foot is free, and the leg's joints for the "
                     "posture task by damped least squares from the measured state (control.ik.ChainIK) "
                     "to the "
                     "tolerance in values.swing_leg_ik",
        "controller": "whole-body inverse dynamics QP (control/wbc), with joint-friction feed-forward",
    }


def _outcome(ctx: RunContext, models: Models, schedule: Schedule, log: ExciteLog,
             design: tuple[list[ExcitationDesign], float], fell: str | None) -> Outcome:
    """The summary lines; passed: did not fall (as far as the plant says) and was not stopped."""
    (waist, arm), shrink = design
    v, watch = ctx.values, schedule.watch
    if fell:
        state = "FELL: " + fell
    elif watch.stopped_at_s is not None:
        state = f"STOPPED into a stance at t={watch.stopped_at_s:.2f} s: {watch.stop_reason}"
    else:
        state = "stood" if v["fell"] is not None else "fall not checked (no truth log)"
    others = v["samples_with_other_contacts"]
    lines = [f"excite g1: {v['duration_s']:.1f} s on its feet ({state}); regressor condition numbers: waist "
             f"{waist.condition_number:.3g} (random start {waist.initial_condition_number:.3g}), arm "
             f"{arm.condition_number:.3g} (random start {arm.initial_condition_number:.3g}); amplitude "
             f"x{shrink:.2f} for {CLEARANCE_M * 100:g} cm clearance, {len(schedule.steps)} steps, CoM RMS "
             f"{v['com_error_rms_m'] * 1e3:.1f} mm ({v['com_error_from']})"
             + ("" if others is None else f", {others} rows with contacts elsewhere"),
             f"balance: min margin {v['min_balance_margin_m'] * 1e3:.1f} mm at "
             f"t={v['min_balance_margin_at_s']:.2f} s"
             + "".join(f"; scaled to x{s:.2f} at t={t:.2f} s ({why})" for t, s, _, why in watch.scalings),
             f"log: {len(log.t)} rows in {CSV_NAME}; identify it with: mbctl identify {ctx.output_dir}"]
    if schedule.legs.solves:
        lines.insert(1, schedule.legs.line())
    if models.options.hidden or models.options.controller_model:
        lines.insert(1, models_line(models.section())
                     + (f"; {SAME_TRAJECTORY}" if models.options.controller_model else ""))
    lines[1:1] = plant_lines(v)
    passed = fell is None and watch.stopped_at_s is None
    return Outcome(passed, tuple(lines), "did not fall and was not stopped by the balance watch")
