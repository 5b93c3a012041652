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

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from mbctl.control.loop import run
from mbctl.control.wbc import Scheduled
from mbctl.jobs.excite import DEFAULT_DURATION_S, ExciteParams, log_section
from mbctl.jobs.excite_g1_legs import SwingLegs
from mbctl.jobs.g1_wbc import g1_whole_body
from mbctl.jobs.ident_log import CSV_NAME, SECTION, header, log_row
from mbctl.jobs.model_options import Models, build_models, models_line
from mbctl.jobs.plots import new_figure
from mbctl.jobs.runner import Outcome, RunContext, Work
from mbctl.planners.excitation import ExcitationDesign, ExcitationLimits, design_excitation
from mbctl.planners.fourier import FourierTrajectory
from mbctl.robots.collision import SelfClearance
from mbctl.robots.commands import Command
from mbctl.robots.edits import position_to_motor, weld_base
from mbctl.robots.g1 import (
    FEET,
    FOOT_BODIES,
    G1_FALL,
    KEYFRAME,
    PELVIS,
    TORSO,
    crouched_start,
    joint_role,
    limb_of,
    with_palm_sites,
)
from mbctl.robots.identification.threads import single_threaded_blas
from mbctl.robots.interface import RobotState
from mbctl.robots.model_pair import Robot
from mbctl.sim.monitor import PlantMonitor
from mbctl.sim.recorder import CsvStream
from mbctl.sim.simulator import Simulator

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
#: CoM motion: amplitude [m] and frequency [Hz] along x, y (sway) and z (squat depth).
COM_AMPLITUDE_M = (0.02, 0.035, 0.04)
COM_FREQUENCY_HZ = (0.23, 0.31, 0.4)
#: Pelvis roll and pitch: amplitude [rad] and frequencies [Hz].
PELVIS_AMPLITUDE_RAD = 0.05
PELVIS_FREQUENCY_HZ = (0.17, 0.27)
#: Ramp-in [s] of every motion from standing still.
RAMP_S = 1.5
#: A step phase: shift the CoM over the other foot, unload, lift, hold, lower, reload, shift back [s].
STEP_TIMES_S = (1.5, 0.6, 0.8, 1.0, 0.8, 0.6, 1.5)
#: Fraction by which the upper body's and the pelvis's motion shrink while the CoM is over one foot.
STEP_CALM = 0.8
#: Height [m] a foot is lifted to during a step (straight up from where it left the floor).
LIFT_HEIGHT_M = 0.05
#: The steps run only in excitations at least this long [s].
MIN_DURATION_FOR_STEPS_S = 16.0


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
                                         seed=params.seed, max_iterations=20))
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


@dataclass
class _Schedule:
    """Task references over time: CoM, pelvis and torso orientation, posture, contacts."""

    wb: Any           # what g1_whole_body returns (its controller and com/pelvis/torso/posture tasks)
    robot: Robot      # the plant's robot (joint names and indices)
    model: pin.Model  # the controller's model (the schedule's own kinematics)
    upper: FourierTrajectory
    q0: np.ndarray
    steps: list[tuple[str, float]]

    def __post_init__(self) -> None:
        model = self.model
        self.data = model.createData()
        self.iq_upper = np.array([self.robot.joint(j).idx_q for j in self.upper.names])
        self.feet_fid = {f: model.getFrameId(f) for f in FEET}
        self.torso_fid, self.pelvis_fid = model.getFrameId(TORSO), model.getFrameId(PELVIS)
        pin.framesForwardKinematics(model, self.data, self.q0)
        self.feet_y = {f: float(self.data.oMf[fid].translation[1]) for f, fid in self.feet_fid.items()}
        self.c0 = np.array(pin.centerOfMass(model, self.data, self.q0))
        self.com_ref = self.c0.copy()
        self.released: set[str] = set()  # steps whose foot was released
        self.landed: set[str] = set()    # steps whose foot was put down again
        self.lift_off: dict[str, pin.SE3] = {}  # where each free foot left the floor
        self.legs = SwingLegs(model, FEET)  # each foot's leg IK, and its record

    def _orientation_torso(self, R_pelvis: np.ndarray, q: np.ndarray) -> np.ndarray:
        """The torso's world orientation with the pelvis at R_pelvis and the waist at q's."""
        model = self.model
        pin.framesForwardKinematics(model, self.data, q)
        X_PT = self.data.oMf[self.pelvis_fid].actInv(self.data.oMf[self.torso_fid])
        return R_pelvis @ X_PT.rotation

    def update(self, t: float, state: RobotState) -> None:
        """Set every task's reference for time ``t`` [s] at the measured ``state``."""
        step = self._step_phase(t, state)
        ramp = _smooth(t / RAMP_S)
        # over one foot the upper body and the pelvis calm down: a small sole bears little moment
        calm = ramp * (1.0 - STEP_CALM * (step[1] if step is not None else 0.0))
        q_ref = self.q0.copy()
        q_up, _, _ = self.upper.sample([t])
        start = self.upper.q_start  # the opened arms the oscillation starts from, at rest
        q_ref[self.iq_upper] = (self.q0[self.iq_upper] + ramp * (start - self.q0[self.iq_upper])
                                + calm * (q_up[0] - start))
        w = 2 * np.pi * np.asarray(COM_FREQUENCY_HZ)
        A = np.asarray(COM_AMPLITUDE_M)
        sway = np.array([A[0] * np.sin(w[0] * t), A[1] * np.sin(w[1] * t), -A[2] * (1 - np.cos(w[2] * t))])
        dsway = np.array([A[0] * w[0] * np.cos(w[0] * t), A[1] * w[1] * np.cos(w[1] * t),
                          -A[2] * w[2] * np.sin(w[2] * t)])
        ddsway = np.array([-A[0] * w[0] ** 2 * np.sin(w[0] * t), -A[1] * w[1] ** 2 * np.sin(w[1] * t),
                           -A[2] * w[2] ** 2 * np.cos(w[2] * t)])
        com, dcom, ddcom = self.c0 + ramp * sway, ramp * dsway, ramp * ddsway
        if step is not None:  # a step: the CoM over the stance foot, sway and squat paused
            foot, s_shift, height = step
            stance_y = self.feet_y[FEET[1] if foot == FEET[0] else FEET[0]]
            com = com + s_shift * (np.array([self.c0[0], stance_y, self.c0[2]]) - com)
            dcom, ddcom = (1 - s_shift) * dcom, (1 - s_shift) * ddcom
            if foot in self.lift_off:
                target = pin.SE3(self.lift_off[foot].rotation,
                                 self.lift_off[foot].translation + [0.0, 0.0, height])
                self._swing_leg(t, q_ref, state, foot, target)
        self.com_ref = com
        self.wb.com.set_target(com, dcom, ddcom)
        wp = 2 * np.pi * np.asarray(PELVIS_FREQUENCY_HZ)
        roll, pitch = calm * PELVIS_AMPLITUDE_RAD * np.sin(wp * t)
        R_pelvis = pin.rpy.rpyToMatrix(roll, pitch, 0.0)
        self.wb.base.set_target(pin.SE3(R_pelvis, np.zeros(3)))
        q_fk = q_ref.copy()
        q_fk[:7] = [0, 0, 0, 0, 0, 0, 1]
        self.wb.torso.set_target(pin.SE3(self._orientation_torso(R_pelvis, q_fk), np.zeros(3)))
        self.wb.posture.set_target(q_ref)

    def _swing_leg(self, t: float, q_ref: np.ndarray, state: RobotState, foot: str, X_WF: pin.SE3) -> None:
        """Leg joints in ``q_ref`` that put ``foot`` at ``X_WF`` from the measured base pose at ``t`` [s].

        The posture task then carries the free foot straight up and back to where it lifted off,
        whatever the pelvis does meanwhile. A target the leg cannot reach leaves the damped closest
        pose and is counted (:class:`~mbctl.jobs.excite_g1_legs.SwingLegs`), never passed on silently.
        """
        idx_q, q_leg = self.legs.solve(t, foot, X_WF, state.q)
        q_ref[idx_q] = q_leg

    def _step_phase(self, t: float, state: RobotState) -> tuple[str, float, float] | None:
        """(foot, CoM shift fraction, foot height [m]) during a step, else None; drives the contacts.

        Phases (:data:`STEP_TIMES_S`): shift the CoM over the other foot; release the foot (force
        ramp, :data:`STEP_TIMES_S`'s second phase, longer than the controller's ramp); then lift it
        straight up, hold, lower it to where it left the floor; put it down (constraint back, force
        ramp up) when the lowering ends; shift the CoM back.
        """
        shift, _, lift, _, lower, _, back = STEP_TIMES_S
        marks = np.cumsum(STEP_TIMES_S)
        ctrl = self.wb.controller
        for foot, t0 in self.steps:
            tau = t - t0
            if not 0.0 <= tau <= marks[-1]:
                continue
            key = f"{foot}@{t0}"
            s_shift = _smooth(tau / shift) if tau < marks[5] else 1.0 - _smooth((tau - marks[5]) / back)
            if tau >= marks[0] and key not in self.released:
                ctrl.release(foot)
                self.released.add(key)
            height = 0.0
            free = tau >= marks[1] and key not in self.landed
            if free and foot not in self.lift_off:
                pin.framesForwardKinematics(self.model, self.data, np.asarray(state.q))
                self.lift_off[foot] = pin.SE3(self.data.oMf[self.feet_fid[foot]])
            if free and tau < marks[2]:
                height = LIFT_HEIGHT_M * _smooth((tau - marks[1]) / lift)
            elif free and tau < marks[3]:
                height = LIFT_HEIGHT_M
            elif free and tau < marks[4]:
                # down to 2 mm below where it lifted off, so the sole lands flat and pressed
                height = (LIFT_HEIGHT_M + 0.002) * (1.0 - _smooth((tau - marks[3]) / lower)) - 0.002
            elif free:
                ctrl.touch_down(foot)
                self.landed.add(key)
                self.lift_off.pop(foot, None)
            return foot, s_shift, height
        return None


def _smooth(s: float) -> float:
    s = min(max(s, 0.0), 1.0)
    return s * s * (3 - 2 * s)


def prepare_g1(params: ExciteParams, loaded: Robot) -> Work:
    """The G1 in torque mode with palm sites; the upper body's excitation designed (no output yet)."""
    def edit(r: Robot) -> Robot:
        return position_to_motor(with_palm_sites(r))

    models = build_models(edit(loaded), params.models, edit)
    q_start = crouched_start(models.controller)
    upper, designs, shrink = design_upper_body(models.controller, q_start, params)
    duration = params.duration or DEFAULT_DURATION_S

    def work(ctx: RunContext) -> Outcome:
        with single_threaded_blas():  # the whole-body QP's matrices are small: threads only cost
            return _run(ctx, params, models, q_start, upper, designs, shrink, duration)

    return work


def _run(ctx: RunContext, params: ExciteParams, models: Models, q_start: np.ndarray,
         upper: FourierTrajectory, designs: list[ExcitationDesign], shrink: float, duration: float
         ) -> Outcome:
    plant = models.plant
    sim = ctx.attach(Simulator(plant), contact_forces=True)
    sim.reset(KEYFRAME)
    sim.set_state(q_start, np.zeros(plant.nv))
    wb = g1_whole_body(plant, models.controller_model)
    wb.hold(sim.read_state())
    steps: list[tuple[str, float]] = []
    if duration >= MIN_DURATION_FOR_STEPS_S:
        total = sum(STEP_TIMES_S)
        steps = [(FEET[0], 0.45 * duration - total), (FEET[1], 0.8 * duration - total)]
    schedule = _Schedule(wb, plant, models.controller_model, upper, q_start.copy(), steps)
    bodies = FOOT_BODIES
    joints = tuple(a.joint for a in plant.actuators.values())  # the controller's order: actuators
    # what the log records, measured by the plant each period: the actuators' torques, the feet's
    # contact wrenches, contacts elsewhere on the robot, its CoM, and whether it fell (G1_FALL)
    monitor = PlantMonitor(sim, fall_rule=G1_FALL.reason, joints=joints, wrench_bodies=bodies,
                           count_elsewhere=True).attach()
    excitation: dict[str, Any] = {
        "kind": "whole-body control on the feet: upper-body Fourier excitation, CoM squat and sway, pelvis "
                "roll and pitch, steps",
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
        "swing_leg": "foot pose task, damped least squares on the leg's joints from the measured state "
                     "(control.ik.ChainIK) to the tolerance in values.swing_leg_ik",
        "controller": "whole-body inverse dynamics QP (control/wbc)",
    }
    dt = sim.control_period_s
    ctx.sections[SECTION] = log_section(params, models.controller, joints, bodies, dt, excitation)
    ctx.sections["plant"] = models.section()
    log = _Log(ctx.open_csv(header(plant, joints, bodies), CSV_NAME), schedule, monitor, ctx.progress.advance)
    ctx.progress.start(max(1, int(round(duration / dt))), "excite g1")
    # the schedule moves the task targets from the measured state (the swing leg's IK starts at the
    # base's pose): the plant's state now is the one the loop just read (no time passes between)
    controller = Scheduled(wb.controller, schedule.update)
    run(sim, controller, None, duration, on_step=log.on_step)
    fell = (None if monitor.fall_reason is None
            else f"{monitor.fall_reason} at t={monitor.fall_time_s:.2f} s")
    com_err = np.asarray(log.com) - np.asarray(log.com_ref)
    ctx.values.update({"duration_s": sim.time_s, "rows": len(log.t), "fell": fell is not None,
                       "fall_reason": fell, "com_error_rms_m": float(np.sqrt(np.mean(np.sum(com_err**2, 1)))),
                       "waist_condition_number": designs[0].condition_number,
                       "arm_condition_number": designs[1].condition_number,
                       "samples_with_other_contacts": log.rows_with_other_contacts,
                       "swing_leg_ik": schedule.legs.section()})
    _plot(ctx, log, bodies, joints, fell)
    lines = [f"excite g1: {sim.time_s:.1f} s on its feet ({'FELL: ' + fell if fell else 'stood'}); "
             f"regressor condition numbers: waist {designs[0].condition_number:.3g} (random start "
             f"{designs[0].initial_condition_number:.3g}), arm {designs[1].condition_number:.3g} (random "
             f"start {designs[1].initial_condition_number:.3g}); amplitude x{shrink:.2f} for "
             f"{CLEARANCE_M * 100:g} cm clearance, {len(steps)} steps, CoM RMS "
             f"{ctx.values['com_error_rms_m'] * 1e3:.1f} mm, "
             f"{log.rows_with_other_contacts} rows with contacts elsewhere",
             f"log: {len(log.t)} rows in {CSV_NAME}; identify it with: mbctl identify {ctx.output_dir}"]
    if schedule.legs.solves:
        lines.insert(1, schedule.legs.line())
    if models.options.hidden or models.options.controller_model:
        lines.insert(1, models_line(models.section()))
    return Outcome(fell is None, tuple(lines), "did not fall")


class _Log:
    """Each control cycle (the loop's ``on_step``): the identification log's row, from the plant monitor.

    Also kept for the report and the plot: times [s], the CoM reference and the plant's CoM (3,)
    [m] at the row's time, the feet's normal forces [N] and the actuators' torques [N m].
    """

    def __init__(self, csv: CsvStream, schedule: _Schedule, monitor: PlantMonitor, tick: Callable[[], None]):
        self.csv, self.schedule, self.monitor, self.tick = csv, schedule, monitor, tick
        self.t: list[float] = []
        self.com_ref: list[np.ndarray] = []
        self.com: list[np.ndarray] = []
        self.fz: list[np.ndarray] = []
        self.tau: list[np.ndarray] = []
        self.rows_with_other_contacts = 0

    def on_step(self, k: int, state: RobotState, reference: object, command: Command) -> bool:
        """Write cycle ``k``'s row; True (end the run) once the robot fell."""
        monitor = self.monitor
        self.csv.write(log_row(state, monitor))
        self.rows_with_other_contacts += monitor.contacts_elsewhere > 0
        self.t.append(state.time_s)
        self.com_ref.append(self.schedule.com_ref.copy())
        self.com.append(monitor.com_W)
        self.fz.append(monitor.wrenches_W[:, 2].copy())
        self.tau.append(monitor.joint_torques)
        self.tick()
        return monitor.fall_reason is not None


def _plot(ctx: RunContext, log: _Log, bodies: tuple[str, ...], joints: tuple[str, ...],
          fell: str | None) -> None:
    """CoM (reference dashed), the feet's normal forces, and the torques of the most loaded joints."""
    t = np.asarray(log.t)
    fig, axes = new_figure(3, 1, (12.0, 9.0), layout="constrained")
    com, ref = np.asarray(log.com), np.asarray(log.com_ref)
    for i, (axis, color) in enumerate(zip("xyz", ("tab:red", "tab:green", "tab:blue"), strict=True)):
        axes[0][0].plot(t, (com[:, i] - ref[0, i]) * 1e3, color=color, lw=1.2, label=f"CoM {axis}")
        axes[0][0].plot(t, (ref[:, i] - ref[0, i]) * 1e3, "--", color=color, lw=0.8)
    axes[0][0].set_ylabel("CoM - start (mm)")
    axes[0][0].set_title("CoM measured in MuJoCo (solid) and its reference (dashed)"
                         + (f"; FELL: {fell}" if fell else ""), fontsize=10)
    fz = np.asarray(log.fz)
    for k, b in enumerate(bodies):
        axes[1][0].plot(t, fz[:, k], lw=1.0, label=b)
    axes[1][0].set_ylabel("normal force (N)")
    axes[1][0].set_title("contact force on each foot (MuJoCo)", fontsize=10)
    tau = np.asarray(log.tau)
    top = np.argsort(-np.abs(tau).max(0))[:6]
    for i in top:
        axes[2][0].plot(t, tau[:, i], lw=0.9, label=joints[i])
    axes[2][0].set_ylabel("applied torque (N m)")
    axes[2][0].set_xlabel("time (s)")
    axes[2][0].set_title("the six most loaded joints", fontsize=10)
    for r in range(3):
        axes[r][0].grid(True, alpha=0.3)
        axes[r][0].legend(fontsize=8, loc="upper right", ncol=3)
    ctx.save_figure(fig, "excite.png")
