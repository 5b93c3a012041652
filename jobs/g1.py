"""G1 control jobs: stand under PD + gravity, computed torque on a welded base, arm PD via targets.

``g1_stand``
    Floating base on the floor, Menagerie position actuators converted to torque motors
    (``position_to_motor``), joint PD + gravity compensation ``g(q)`` holding the ``stand``
    keyframe. Gains come from ``omega``, ``zeta`` and a *stance inertia* per joint: arm and waist
    joints use ``M_jj(q)`` (the subtree they move); leg joints carry the body above them, so they
    use ``max(M_jj, m d_j^2 / 2)`` with m the robot mass and d_j the distance from the joint to
    the centre of mass (half the body per leg); each D gain is then kept below the joint's own
    inertia over 10 ms (:func:`damping_with_margin`: a light foot stays stable with the loop's delay).
``g1_track``
    Pelvis welded at the keyframe pose (``weld_base``), torque motors, joint-space computed
    torque following jerk-limited ruckig trajectories through waypoints that move both arms,
    both legs and the waist; legs start bent so the feet stay clear of the floor.
``g1_arm_pd``
    Floating base on the floor with the Menagerie position actuators; one arm follows a ruckig
    trajectory through position targets (``PositionTargetPD``: the actuators' PD plus a gravity
    feed-forward offset); every other actuator keeps the keyframe's targets.

Every job runs on the job runner: a CSV streamed one row per control cycle (reference, full q,
v, command; ``base_z_m`` for the robots on the floor), ``report.json`` with the status and values,
and a PNG. The verdict (exit 1 when missed): the robot on the floor did not fall (pelvis within
``PELVIS_BOUND_M`` of the keyframe height, and not fallen by the G1's fall rule
(``mbctl.robots.g1.G1_FALL``: pelvis below 0.5 m or a body other than the feet on the floor,
measured by a ``PlantMonitor`` in-process, from the bridge's truth log over DDS) and, when given,
the joint RMS error bound.

Plots: ``jobs/g1_plots.py``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from mbctl.control.computed_torque import ComputedTorque
from mbctl.control.controller import ControllerBase, joint_reference
from mbctl.control.exceptions import ControlError, ControllerSetupError
from mbctl.control.gains import PDGains, gains_from_frequency
from mbctl.control.loop import RunLog, run
from mbctl.control.pd_gravity import PDGravity
from mbctl.control.position_pd import PositionTargetPD
from mbctl.jobs.g1_plots import stand_plot, tracking_plot
from mbctl.jobs.g1_references import ARM_LIMITS, arm_trajectory, track_waypoints
from mbctl.jobs.model_options import ModelOptions, build_models, models_line
from mbctl.jobs.plant import Plant, PlantOptions, dry_run, plant_lines, prepare_plant, report_plant
from mbctl.jobs.recording import LoopRows, command_columns
from mbctl.jobs.runner import Job, Outcome, RunContext, Work
from mbctl.limits import check_duration
from mbctl.planners.ruckig_planner import JointLimits, plan_waypoints
from mbctl.planners.trajectory import JointTrajectory
from mbctl.robots.edits import position_to_motor, weld_base
from mbctl.robots.g1 import G1_FALL, KEYFRAME, LEG_WORDS
from mbctl.robots.interface import RobotInterface, RobotState
from mbctl.robots.model_pair import Robot
from mbctl.robots.registry import load_robot
from mbctl.sim.monitor import PlantMonitor
from mbctl.sim.simulator import Simulator

#: Joint limits of the tracking trajectories: velocity [rad/s], acceleration [rad/s^2],
#: jerk [rad/s^3] (well inside the G1's actuator capabilities).
TRACK_LIMITS = (2.0, 10.0, 80.0)


def stance_inertia(robot: Robot, q: np.ndarray, joints: tuple[str, ...]) -> np.ndarray:
    """Per-joint inertia [kg m^2] for standing gains (see the module docstring).

    Args:
        robot: The floating-base robot.
        q: Configuration (nq,), Pinocchio convention.
        joints: Controlled joint names.
    """
    model = robot.pin_model
    data = model.createData()
    M = pin.crba(model, data, q)
    com = pin.centerOfMass(model, data, q)  # also places the joints (data.oMi)
    mass = pin.computeTotalMass(model)
    out = np.empty(len(joints))
    for i, name in enumerate(joints):
        layout = robot.joint(name)
        out[i] = M[layout.idx_v, layout.idx_v]
        if any(w in name for w in LEG_WORDS):
            d = float(np.linalg.norm(com - data.oMi[model.getJointId(name)].translation))
            out[i] = max(out[i], 0.5 * mass * d * d)
    return out


#: The longest loop delay [s] g1-stand's damping keeps its margin at: Unitree's simulator at its
#: 5 ms publishes the sensors of the step before, so a command acts two periods after the state it
#: came from (the G1 at 2 ms: one to two periods, 2-4 ms).
MARGIN_DELAY_S = 0.01


def damping_with_margin(gains: PDGains, robot: Robot, q: np.ndarray, joints: tuple[str, ...]) -> PDGains:
    """``gains`` with each D gain at most the joint's own inertia M_jj(q) over :data:`MARGIN_DELAY_S`.

    A sampled loop applies its damping explicitly and late: a link whose own inertia is small (a
    foot off the floor: its ankle's M_jj is ~0.03 kg m^2, its stance inertia ~9 kg m^2) stays
    stable only while kd tau / M_jj stays small (explicit damping diverges from 2). Keeping it <= 1
    at 10 ms of delay: on Unitree's G1 model at its 5 ms, g1-stand stands from omega 8 to 10 rad/s
    (falls at 12, and at 10 without this); the stiffness is kept (it carries the stance).
    """
    M = pin.crba(robot.pin_model, robot.pin_model.createData(), q)
    own = np.array([M[robot.joint(j).idx_v, robot.joint(j).idx_v] for j in joints])
    return PDGains(gains.kp, np.minimum(gains.kd, own / MARGIN_DELAY_S))


#: Pelvis height change [m] a standing job must stay within (a bound on standing quality; whether
#: the robot fell is the G1's one fall rule, ``mbctl.robots.g1.G1_FALL``, measured in the plant).
PELVIS_BOUND_M = 0.02


def _positive(name: str, value: float | None, allow_none: bool = True) -> None:
    if value is None and allow_none:
        return
    if value is None or not (np.isfinite(value) and value > 0):
        raise ControllerSetupError(f"{name} must be finite and > 0; got {value}")


@dataclass(frozen=True)
class StandParams:
    """``mbctl g1-stand``: duration [s], omega [rad/s], zeta [-], model directory, plant, models."""

    duration_s: float = 10.0
    omega_rad_s: float = 10.0
    zeta: float = 1.0
    model_dir: str | None = None
    plant: PlantOptions = PlantOptions()
    models: ModelOptions = ModelOptions()

    def __post_init__(self) -> None:
        self.plant.check_models(self.models)
        for name in ("duration_s", "omega_rad_s", "zeta"):
            _positive(name, getattr(self, name), allow_none=False)
        self.plant.check_duration(self.duration_s)


@dataclass(frozen=True)
class TrackParams:
    """``mbctl g1-track``: duration [s] (None: whole trajectory), omega [rad/s], zeta, RMS bound [rad]."""

    duration_s: float | None = None
    omega_rad_s: float = 40.0
    zeta: float = 1.0
    max_rms_error_rad: float | None = None
    model_dir: str | None = None
    models: ModelOptions = ModelOptions()

    def __post_init__(self) -> None:
        check_duration(self.duration_s)
        _positive("duration_s", self.duration_s)
        _positive("omega_rad_s", self.omega_rad_s, allow_none=False)
        _positive("zeta", self.zeta, allow_none=False)
        _positive("max_rms_error_rad", self.max_rms_error_rad)


@dataclass(frozen=True)
class ArmPDParams:
    """``mbctl g1-arm-pd``: duration [s] (None: whole trajectory), arm side, feed-forward, bound [rad]."""

    duration_s: float | None = None
    side: str = "left"
    gravity_feedforward: bool = True
    max_rms_error_rad: float | None = None
    model_dir: str | None = None
    plant: PlantOptions = PlantOptions()
    models: ModelOptions = ModelOptions()

    def __post_init__(self) -> None:
        self.plant.check_models(self.models)
        if self.side not in ("left", "right"):
            raise ControlError(f"side must be 'left' or 'right'; got {self.side!r}")
        _positive("duration_s", self.duration_s)
        _positive("max_rms_error_rad", self.max_rms_error_rad)
        self.plant.check_duration(self.duration_s)


def _base_z_index(robot: Robot) -> int:
    """Index in q of the floating base's height z (Pinocchio convention)."""
    base = next(j for j in robot.joints.values() if j.kind == "free")
    return base.idx_q + 2


def _loop(ctx: RunContext, sim: RobotInterface, controller: PDGravity | ComputedTorque | PositionTargetPD,
          reference: Any, duration_s: float, unit: str, label: str, base_z: bool = False) -> RunLog:
    """Run the control loop with every cycle streamed to the run's CSV and the progress bar.

    Args:
        ctx: The run.
        sim: The plant (an in-process one is attached to the run, for replay and video, by its maker).
        controller: The control law.
        reference: What ``control.loop.run`` takes as the reference.
        duration_s: Simulated time [s].
        unit: The command's unit ("N_m" torques, "rad" position targets).
        label: Progress bar label.
        base_z: Add a ``base_z_m`` column (floating-base height [m]).
    """
    joints = controller.joints
    extra_names = ["base_z_m"] if base_z else []
    header = LoopRows.header(sim.robot, [f"q_ref_{j}_rad" for j in joints], command_columns(joints, unit),
                             extra_names)
    extra = None
    if base_z:
        zi = _base_z_index(sim.robot)

        def extra(state: RobotState) -> list[float]:
            return [float(state.q[zi])]

    ctx.progress.start(max(1, int(round(duration_s / sim.control_period_s))), label)
    rows = LoopRows(ctx.open_csv(header), len(joints), extra, ctx.progress.advance)
    return run(sim, controller, reference, duration_s, rows)


def prepare_stand(params: StandParams, robot: Robot | None = None) -> Work:
    """Load the G1, convert its actuators to motors and derive the standing gains (no output yet)."""
    models = build_models(position_to_motor(robot or load_robot("g1", model_dir=params.model_dir)),
                          params.models, position_to_motor)
    robot = models.plant
    q0 = robot.keyframe_q(KEYFRAME)
    probe = PDGravity(robot, PDGains(np.ones(1), np.ones(1)))
    inertia = stance_inertia(models.controller, q0, probe.joints)
    gains = damping_with_margin(gains_from_frequency(params.omega_rad_s, params.zeta, inertia),
                                models.controller, q0, probe.joints)
    plant = prepare_plant(params.plant, robot, KEYFRAME)

    def work(ctx: RunContext) -> Outcome:
        with plant(ctx) as p:
            ctx.sections["models"] = models.section()
            return _stand(ctx, params, robot, gains, inertia, q0, p, models.controller_model)

    return work


def _stand(ctx: RunContext, params: StandParams, robot: Robot, gains: PDGains, inertia: np.ndarray,
           q0: np.ndarray, p: Plant, pin_model: pin.Model) -> Outcome:
    sim = p.interface
    if p.options.dry_run:
        return dry_run(ctx, p, params.duration_s)
    controller = PDGravity(robot, gains, pin_model=pin_model)
    ctx.sections["inputs"] = {"keyframe": KEYFRAME, "controller": "pd_gravity"}
    ctx.sections["gains"] = {
        "kp_N_m_rad": dict(zip(controller.joints, controller.gains.kp.tolist(), strict=True)),
        "kd_N_m_s_rad": dict(zip(controller.joints, controller.gains.kd.tolist(), strict=True)),
        "inertia_kg_m2": dict(zip(controller.joints, inertia.tolist(), strict=True)),
    }
    z0 = float(q0[_base_z_index(robot)])
    ctx.values["pelvis_z_keyframe_m"] = float(z0)
    reference = joint_reference(q0[controller.joint_map.idx_q])
    monitor = _fall_monitor(p)
    log = _loop(ctx, sim, controller, reference, params.duration_s, "N_m", "g1-stand", base_z=True)
    zi = _base_z_index(robot)
    stats, error = log.sums(), log.error_sums()
    z_final = float(sim.read_state().q[zi])
    # every cycle's pelvis height (the loop's sums) and the final state's
    z_min, z_max = min(float(stats.q.min[zi]), z_final), max(float(stats.q.max[zi]), z_final)
    reason = _fall_reason(ctx, p, log, monitor, z_min)
    fell = reason is not None
    max_dev = max(z_max - z0, z0 - z_min)
    off = _off_bound(ctx, max_dev)
    ctx.values.update({
        "pelvis_z_min_m": z_min,
        "pelvis_z_max_m": z_max,
        "pelvis_z_final_m": z_final,
        "pelvis_max_deviation_m": max_dev,
        "fell": fell,
        "fall_reason": reason,
        "joint_rms_error_rad": error.rms_all(),
        "joint_max_error_rad": float(error.max_abs().max()),
        "saturated_cycles": controller.saturation.saturated_cycles,
        "simulated_time_s": sim.time_s,
        "wall_time_s": log.wall_time_s,
    })
    ctx.sections["controller_saturation"] = controller.saturation.summary()
    joint_err = log.reference - log.q[:, controller.joint_map.idx_q]  # the rows kept, for the plot
    stand_plot(ctx, log, log.q[:, zi] - z0, -joint_err, controller.joints, params.omega_rad_s, params.zeta,
               PELVIS_BOUND_M)
    v = ctx.values
    return Outcome(not (fell or off), (
        f"g1-stand {params.duration_s:g} s, PD + gravity (omega {params.omega_rad_s:g} rad/s, zeta "
        f"{params.zeta:g}): {'FELL (' + str(reason) + ')' if fell else 'stood'}, pelvis max "
        f"deviation {v['pelvis_max_deviation_m'] * 1e3:.2f} mm, joint RMS error "
        f"{v['joint_rms_error_rad']:.3e} rad, saturated cycles {v['saturated_cycles']}", *plant_lines(v),
        *_models_lines(ctx),
    ), f"did not fall; pelvis within {PELVIS_BOUND_M * 1e3:g} mm of the keyframe height")


def _models_lines(ctx: RunContext) -> list[str]:
    """The summary line of the model options, when the plant or the controller's model is not the robot's."""
    section = ctx.sections.get("models")
    if not section or (section["payload"] is None and not section["plant_error_pct"]
                       and section["controller_model"] == "the robot's own"):
        return []
    return [models_line(section)]


def _fall_monitor(p: Plant) -> PlantMonitor | None:
    """The G1's fall rule on the in-process plant (None over DDS: the truth log says it there)."""
    return PlantMonitor(p.sim, fall_rule=G1_FALL.reason).attach() if p.sim is not None else None


def _fall_reason(ctx: RunContext, p: Plant, log: RunLog, monitor: PlantMonitor | None,
                 z_min: float) -> str | None:
    """Why the G1 fell, by its one rule: the plant's monitor, the bridge's truth log, else the state.

    ``z_min`` [m]: the lowest estimated pelvis height of the run (the client's only view of it).
    """
    truth_fell = report_plant(ctx, p, log, G1_FALL.base_min_z_m)
    if monitor is not None:
        return monitor.fall_reason
    if truth_fell is not None:
        return "pelvis below its fall height (truth log)" if truth_fell else None
    return G1_FALL.reason(z_min, ())


def _off_bound(ctx: RunContext, estimated_deviation_m: float) -> bool:
    """The pelvis moved more than PELVIS_BOUND_M (the truth log's word over the estimate's)."""
    deviation = ctx.values.get("truth_pelvis_max_deviation_m", estimated_deviation_m)
    return bool(deviation > PELVIS_BOUND_M)


def prepare_track(params: TrackParams, robot: Robot | None = None) -> Work:
    """Load and weld the G1, convert to motors, plan the ruckig trajectory (no output yet)."""
    def edit(r: Robot) -> Robot:
        return position_to_motor(weld_base(r, KEYFRAME))

    models = build_models(edit(robot or load_robot("g1", model_dir=params.model_dir)), params.models, edit)
    robot = models.plant
    names = tuple(robot.joints)
    waypoints = track_waypoints(robot)
    limits = JointLimits.uniform(len(names), *TRACK_LIMITS)
    traj = plan_waypoints(waypoints, limits, robot.timestep_s, names)

    def work(ctx: RunContext) -> Outcome:
        sim = Simulator(robot)
        sim.reset(q=waypoints[0])
        ctx.attach(sim)
        controller = ComputedTorque(robot, gains_from_frequency(params.omega_rad_s, params.zeta),
                                    pin_model=models.controller_model)
        ctx.sections["models"] = models.section()
        duration = params.duration_s or traj.duration_s + 0.2
        ctx.sections["inputs"] = {
            "duration_s": duration, "controller": "computed_torque",
            "limits": {"max_velocity_rad_s": TRACK_LIMITS[0], "max_acceleration_rad_s2": TRACK_LIMITS[1],
                       "max_jerk_rad_s3": TRACK_LIMITS[2]},
            "waypoints_rad": waypoints.tolist()}
        log = _loop(ctx, sim, controller, traj, duration, "N_m", "g1-track")
        return _tracking_outcome(ctx, "g1_track", log, controller, sim, params.max_rms_error_rad, {
            "trajectory_duration_s": traj.duration_s,
            "contacts_at_end": sim.contact_count,
        }, f"G1 welded base, computed torque (omega {params.omega_rad_s:g} rad/s, zeta {params.zeta:g})")

    return work


def _tracking_outcome(ctx: RunContext, name: str, log: RunLog, controller: ControllerBase,
                      sim: RobotInterface, bound: float | None, extra: dict[str, Any], title: str,
                      body: tuple[np.ndarray, np.ndarray, tuple[str, ...], float] | None = None,
                      fall_reason: str | None = None) -> Outcome:
    """Tracking values, the plot and the verdict: the RMS bound (if any) met and the robot standing.

    The figures are over every cycle (the loop's sums), the plot over the log's rows. With ``body``
    (pelvis height change of each row (R,) [m], the other joints' deviation (R, m) [rad], their
    names, and the largest pelvis height change over every cycle [m]) and ``fall_reason`` (the G1's
    fall rule), the robot stands on the floor: a fall, or the pelvis moving more than
    ``PELVIS_BOUND_M``, fails the run too.
    """
    error = log.error_sums()
    rms_by_joint = error.rms()
    rms = error.rms_all()
    err = log.reference - log.q[:, controller.joint_map.idx_q]  # the rows: the last is the last cycle
    ctx.values.update({
        "joint_rms_error_rad": rms,
        "joint_max_error_rad": float(error.max_abs().max()),
        "final_max_error_rad": float(np.abs(err[-1]).max()),
        "worst_joint": controller.joints[int(np.argmax(rms_by_joint))],
        "worst_joint_rms_error_rad": float(rms_by_joint.max()),
        **extra,
        "saturated_cycles": controller.saturation.saturated_cycles,
        "simulated_time_s": sim.time_s,
        "wall_time_s": log.wall_time_s,
        "rms_error_by_joint_rad": dict(zip(controller.joints, rms_by_joint.tolist(), strict=True)),
    })
    ctx.sections["controller_saturation"] = controller.saturation.summary()
    fell = False
    bounds = [] if bound is None else [f"joint RMS error <= {bound:g} rad"]
    lines = [f"{name.replace('_', '-')}: joint RMS error {rms:.3e} rad, "
             f"max {ctx.values['joint_max_error_rad']:.3e} rad, worst joint {ctx.values['worst_joint']} "
             f"({ctx.values['worst_joint_rms_error_rad']:.3e} rad RMS), "
             f"saturated cycles {ctx.values['saturated_cycles']}"]
    if body is not None:
        dz = body[3]
        ctx.values.update({"pelvis_max_deviation_m": dz, "fell": fall_reason is not None,
                           "fall_reason": fall_reason})
        fell = fall_reason is not None or _off_bound(ctx, dz)
        bounds.append(f"did not fall; pelvis within {PELVIS_BOUND_M * 1e3:g} mm of the keyframe height")
        lines.append(f"pelvis max deviation {dz * 1e3:.2f} mm "
                     f"({'FELL (' + fall_reason + ')' if fall_reason is not None else 'stood'})")
    lines += _models_lines(ctx)
    tracking_plot(ctx, name, log, controller.joints, err, f"{title}: joint RMS {rms:.3g} rad",
                  None if body is None else body[:3], bound_m=PELVIS_BOUND_M)
    passed = (bound is None or rms <= bound) and not fell
    return Outcome(passed, tuple(lines), "; ".join(bounds) or None)


def prepare_arm_pd(params: ArmPDParams, robot: Robot | None = None) -> Work:
    """Load the G1 (position actuators) and plan the arm's trajectory (no output yet)."""
    models = build_models(robot or load_robot("g1", model_dir=params.model_dir), params.models)
    robot = models.plant
    traj = arm_trajectory(robot, params.side, robot.timestep_s)
    controller = PositionTargetPD(robot, traj.names, gravity_feedforward=params.gravity_feedforward,
                                  pin_model=models.controller_model)
    others = tuple(a.joint for a in robot.actuators.values() if a.joint not in traj.names)
    params.plant.check_duration(params.duration_s or traj.duration_s + 0.3)  # the whole trajectory's
    # every actuator holds the keyframe's target (DDS: the pose at start); the arm's are overwritten
    plant = prepare_plant(params.plant, robot, KEYFRAME)

    def work(ctx: RunContext) -> Outcome:
        with plant(ctx) as p:
            ctx.sections["models"] = models.section()
            return _arm_pd(ctx, params, robot, traj, controller, others, p)

    return work


def _arm_pd(ctx: RunContext, params: ArmPDParams, robot: Robot, traj: JointTrajectory,
            controller: PositionTargetPD, others: tuple[str, ...], p: Plant) -> Outcome:
    sim = p.interface
    q0 = robot.keyframe_q(KEYFRAME)
    duration = params.duration_s or traj.duration_s + 0.3  # as checked in prepare_arm_pd
    if p.options.dry_run:
        return dry_run(ctx, p, duration)
    z0 = float(q0[_base_z_index(robot)])
    controller.use_gains(sim.position_gains())  # the plant's (over DDS: lowered where unstable)
    ctx.sections["inputs"] = {
        "duration_s": duration, "controller": "position_pd",
        "limits": {"max_velocity_rad_s": ARM_LIMITS[0], "max_acceleration_rad_s2": ARM_LIMITS[1],
                   "max_jerk_rad_s3": ARM_LIMITS[2]},
        "actuator_kp_N_m_rad": controller.kp.tolist(), "actuator_kv_N_m_s_rad": controller.kv.tolist()}
    monitor = _fall_monitor(p)
    log = _loop(ctx, sim, controller, traj, duration, "rad", f"g1-arm-pd ({params.side} arm)",
                base_z=True)
    zi = _base_z_index(robot)
    stats = log.sums()
    idx_others = [robot.joint(j).idx_q for j in others]
    reason = _fall_reason(ctx, p, log, monitor, float(stats.q.min[zi]))
    # every cycle's (the loop's sums); the rows below are for the plot
    max_dz = float(stats.q.max_abs(z0)[zi])
    max_deviation = float(stats.q.max_abs(q0)[idx_others].max())
    dz = log.q[:, zi] - z0
    deviation = log.q[:, idx_others] - q0[idx_others]
    return _tracking_outcome(ctx, "g1_arm_pd", log, controller, sim, params.max_rms_error_rad, {
        "arm": params.side,
        "trajectory_duration_s": traj.duration_s,
        "other_joints_max_deviation_rad": max_deviation,
    }, f"G1 {params.side} arm through the position actuators"
       + (" + gravity feed-forward" if params.gravity_feedforward else ""),
       (dz, deviation, others, max_dz), reason)


#: The G1 jobs.
G1_STAND = Job("g1-stand", prepare_stand)
G1_TRACK = Job("g1-track", prepare_track)
G1_ARM_PD = Job("g1-arm-pd", prepare_arm_pd)
