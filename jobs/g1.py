"""G1 control jobs: stand under PD + gravity, computed torque on a welded base, arm PD via targets.

``g1_stand``
    Floating base on the floor, Menagerie position actuators converted to torque motors
    (``position_to_motor``), joint PD + gravity compensation ``g(q)`` holding the ``stand``
    keyframe. Gains come from ``omega``, ``zeta`` and a *stance inertia* per joint: arm and waist
    joints use ``M_jj(q)`` (the subtree they move); leg joints carry the body above them, so they
    use ``max(M_jj, m d_j^2 / 2)`` with m the robot mass and d_j the distance from the joint to
    the centre of mass (half the body per leg).
``g1_track``
    Pelvis welded at the keyframe pose (``weld_base``), torque motors, joint-space computed
    torque following jerk-limited ruckig trajectories through waypoints that move both arms,
    both legs and the waist; legs start bent so the feet stay clear of the floor.
``g1_arm_pd``
    Floating base on the floor with the Menagerie position actuators; one arm follows a ruckig
    trajectory through position targets (``PositionTargetPD``: the actuators' PD plus a gravity
    feed-forward offset); every other actuator keeps the keyframe's targets.

Every job runs on the job runner: a CSV streamed one row per control cycle (reference, full q,
v, command), ``report.json`` with the status and values, and a PNG.
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
from mbctl.jobs.plots import joint_colors, most_moved, new_figure
from mbctl.jobs.recording import LoopRows, command_columns
from mbctl.jobs.robot_constants import KEYFRAME
from mbctl.jobs.runner import Job, Outcome, RunContext, Work
from mbctl.planners.ruckig_planner import JointLimits, plan_ruckig, plan_waypoints
from mbctl.planners.trajectory import JointTrajectory
from mbctl.robots.edits import position_to_motor, weld_base
from mbctl.robots.model_pair import Robot
from mbctl.robots.registry import load_robot
from mbctl.sim.simulator import Simulator

LEG_WORDS = ("hip", "knee", "ankle")

#: Joint limits of the tracking trajectories: velocity [rad/s], acceleration [rad/s^2],
#: jerk [rad/s^3] (well inside the G1's actuator capabilities).
TRACK_LIMITS = (2.0, 10.0, 80.0)
ARM_LIMITS = (1.5, 6.0, 40.0)


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


def _set(q: np.ndarray, names: list[str], values: dict[str, float]) -> np.ndarray:
    out = q.copy()
    for k, v in values.items():
        out[names.index(k)] = v
    return out


def track_waypoints(robot: Robot) -> np.ndarray:
    """Waypoints (4, nq) [rad] for the welded G1: start (legs bent, feet clear), A, B, start."""
    names = list(robot.joints)
    q0 = robot.keyframe_q(KEYFRAME)
    legs_bent = {f"{s}_{j}_joint": v for s in ("left", "right")
                 for j, v in (("hip_pitch", -0.3), ("knee", 0.6), ("ankle_pitch", -0.3))}
    start = _set(q0, names, legs_bent)
    a = _set(start, names, {
        "left_hip_pitch_joint": -0.6, "left_knee_joint": 1.0, "left_ankle_pitch_joint": -0.3,
        "right_hip_pitch_joint": -0.3, "right_knee_joint": 0.8, "right_ankle_pitch_joint": -0.4,
        "left_shoulder_pitch_joint": -0.8, "left_shoulder_roll_joint": 0.5, "left_elbow_joint": 0.3,
        "right_shoulder_pitch_joint": 0.4, "right_shoulder_roll_joint": -0.4,
        "right_elbow_joint": 1.2, "left_wrist_roll_joint": 0.5, "right_wrist_pitch_joint": -0.4,
        "waist_yaw_joint": 0.3})
    b = _set(start, names, {
        "left_hip_pitch_joint": -0.5, "left_knee_joint": 0.9, "left_hip_roll_joint": 0.25,
        "right_hip_pitch_joint": -0.2, "right_knee_joint": 0.6, "right_hip_roll_joint": -0.25,
        "left_shoulder_pitch_joint": 0.3, "left_shoulder_yaw_joint": 0.4, "left_elbow_joint": 1.0,
        "right_shoulder_pitch_joint": -0.6, "right_shoulder_yaw_joint": -0.3,
        "right_elbow_joint": 0.5, "left_wrist_yaw_joint": -0.5, "right_wrist_roll_joint": 0.4,
        "waist_yaw_joint": -0.2})
    return np.vstack([start, a, b, start])


def arm_trajectory(robot: Robot, side: str, dt_s: float) -> JointTrajectory:
    """A ruckig trajectory of one arm: keyframe -> raised and bent -> keyframe (7 joints)."""
    names = tuple(f"{side}_{j}_joint" for j in ("shoulder_pitch", "shoulder_roll", "shoulder_yaw",
                                                  "elbow", "wrist_roll", "wrist_pitch", "wrist_yaw"))
    q0 = robot.keyframe_q(KEYFRAME)
    start = np.array([q0[robot.joint(n).idx_q] for n in names])
    s = 1.0 if side == "left" else -1.0
    goal = start + np.array([-0.9, 0.4 * s, 0.3 * s, 0.6, 0.4 * s, -0.3, 0.3 * s])
    limits = JointLimits.uniform(len(names), *ARM_LIMITS)
    there = plan_ruckig(start, goal, limits, dt_s, names)
    back = plan_ruckig(goal, start, limits, dt_s, names)
    return there.then(back)



#: Pelvis height change [m] beyond which the standing robot counts as fallen.
FALL_DEVIATION_M = 0.02


def _positive(name: str, value: float | None, allow_none: bool = True) -> None:
    if value is None and allow_none:
        return
    if value is None or not (np.isfinite(value) and value > 0):
        raise ControllerSetupError(f"{name} must be finite and > 0; got {value}")


@dataclass(frozen=True)
class StandParams:
    """``mbctl g1-stand``: duration [s], closed-loop omega [rad/s], zeta [-], model directory."""

    duration_s: float = 10.0
    omega_rad_s: float = 10.0
    zeta: float = 1.0
    model_dir: str | None = None

    def __post_init__(self) -> None:
        for name in ("duration_s", "omega_rad_s", "zeta"):
            _positive(name, getattr(self, name), allow_none=False)


@dataclass(frozen=True)
class TrackParams:
    """``mbctl g1-track``: duration [s] (None: whole trajectory), omega [rad/s], zeta, RMS bound [rad]."""

    duration_s: float | None = None
    omega_rad_s: float = 40.0
    zeta: float = 1.0
    max_rms_error_rad: float | None = None
    model_dir: str | None = None

    def __post_init__(self) -> None:
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

    def __post_init__(self) -> None:
        if self.side not in ("left", "right"):
            raise ControlError(f"side must be 'left' or 'right'; got {self.side!r}")
        _positive("duration_s", self.duration_s)
        _positive("max_rms_error_rad", self.max_rms_error_rad)


def _loop(ctx: RunContext, sim: Simulator, controller: PDGravity | ComputedTorque | PositionTargetPD,
          reference: Any,
          duration_s: float, unit: str, label: str) -> RunLog:
    """Run the control loop with every cycle streamed to the run's CSV and the progress bar."""
    ctx.attach(sim)
    joints = controller.joints
    header = LoopRows.header(sim.robot, [f"q_ref_{j}_rad" for j in joints], command_columns(joints, unit))
    ctx.progress.start(max(1, int(round(duration_s / sim.control_period_s))), label)
    rows = LoopRows(ctx.open_csv(header), len(joints), tick=ctx.progress.advance)
    return run(sim, controller, reference, duration_s, rows)


def _tracking_plot(ctx: RunContext, name: str, log: RunLog, joints: tuple[str, ...], err: np.ndarray,
                   title: str, extra: tuple[str, np.ndarray] | None = None) -> None:
    """Reference (dashed) and plant (solid) of the joints that moved most; their errors in mrad."""
    shown = most_moved(log.reference, 8)
    colors = joint_colors(list(joints))
    panels = 3 if extra is not None else 2
    fig, axes = new_figure(1, panels, (6.0 * panels, 5.0))
    ax, ax_err = axes[0][0], axes[0][1]
    for i in shown:
        c = colors[joints[i]]
        ax.plot(log.t_s, log.reference[:, i], ls="--", lw=1.0, color=c)
        ax.plot(log.t_s, log.reference[:, i] - err[:, i], lw=1.0, color=c, label=joints[i])
        ax_err.plot(log.t_s, err[:, i] * 1e3, lw=0.9, color=c, label=joints[i])
    ax.set_xlabel("time (s)")
    ax.set_ylabel("joint angle (rad)")
    ax.set_title(f"the {len(shown)} joints that moved most (dashed: reference, solid: plant)", fontsize=9)
    ax.legend(fontsize=7, loc="best")
    ax_err.set_xlabel("time (s)")
    ax_err.set_ylabel("joint error q_ref - q (mrad)")
    ax_err.set_title("tracking error, same joints and colours", fontsize=9)
    ax_err.grid(True, alpha=0.3)
    if extra is not None:
        ax3 = axes[0][2]
        ax3.plot(log.t_s, extra[1], color="k", lw=1.0)
        ax3.set_xlabel("time (s)")
        ax3.set_ylabel(extra[0])
        ax3.grid(True, alpha=0.3)
        ax3.set_title("pelvis height change", fontsize=9)
    fig.suptitle(title)
    fig.tight_layout()
    ctx.save_figure(fig, f"{name}.png")


def prepare_stand(params: StandParams, robot: Robot | None = None) -> Work:
    """Load the G1, convert its actuators to motors and derive the standing gains (no output yet)."""
    robot = position_to_motor(robot or load_robot("g1", model_dir=params.model_dir))
    q0 = robot.keyframe_q(KEYFRAME)
    probe = PDGravity(robot, PDGains(np.ones(1), np.ones(1)))
    inertia = stance_inertia(robot, q0, probe.joints)
    gains = gains_from_frequency(params.omega_rad_s, params.zeta, inertia)

    def work(ctx: RunContext) -> Outcome:
        sim = Simulator(robot)
        sim.reset(KEYFRAME)
        controller = PDGravity(robot, gains)
        ctx.sections["inputs"] = {"keyframe": KEYFRAME, "controller": "pd_gravity"}
        ctx.sections["gains"] = {
            "kp_N_m_rad": dict(zip(controller.joints, controller.gains.kp.tolist(), strict=True)),
            "kd_N_m_s_rad": dict(zip(controller.joints, controller.gains.kd.tolist(), strict=True)),
            "inertia_kg_m2": dict(zip(controller.joints, inertia.tolist(), strict=True)),
        }
        z0 = sim.base_z_m
        ctx.values["pelvis_z_keyframe_m"] = float(z0)
        reference = joint_reference(q0[controller.joint_map.idx_q])
        log = _loop(ctx, sim, controller, reference, params.duration_s, "N_m", "g1-stand")
        z = np.append(log.q[:, 2], sim.base_z_m)
        dev = z - z0
        joint_err = log.reference - log.q[:, controller.joint_map.idx_q]
        fell = bool(np.abs(dev).max() > FALL_DEVIATION_M)
        ctx.values.update({
            "pelvis_z_min_m": float(z.min()),
            "pelvis_z_max_m": float(z.max()),
            "pelvis_z_final_m": float(z[-1]),
            "pelvis_max_deviation_m": float(np.abs(dev).max()),
            "fell": fell,
            "joint_rms_error_rad": float(np.sqrt(np.mean(joint_err**2))),
            "joint_max_error_rad": float(np.abs(joint_err).max()),
            "saturated_cycles": controller.saturation.saturated_cycles,
            "simulated_time_s": sim.time_s,
            "wall_time_s": log.wall_time_s,
        })
        ctx.sections["controller_saturation"] = controller.saturation.summary()
        _stand_plot(ctx, log, dev[:-1], controller.joints, params)
        v = ctx.values
        return Outcome(not fell, (
            f"g1-stand {params.duration_s:g} s, PD + gravity (omega {params.omega_rad_s:g} rad/s, zeta "
            f"{params.zeta:g}): pelvis max deviation {v['pelvis_max_deviation_m'] * 1e3:.2f} mm "
            f"({'FELL' if fell else 'stood'}), joint RMS error {v['joint_rms_error_rad']:.3e} rad, "
            f"saturated cycles {v['saturated_cycles']}",
        ), f"pelvis within {FALL_DEVIATION_M * 1e3:g} mm of the keyframe height")

    return work


def _stand_plot(ctx: RunContext, log: RunLog, dev: np.ndarray, joints: tuple[str, ...],
                params: StandParams) -> None:
    fig, axes = new_figure(1, 2, (13.0, 5.0))
    ax, ax2 = axes[0]
    ax.plot(log.t_s, dev * 1e3, color="k", lw=1.0, label="pelvis height - keyframe")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("pelvis height change (mm)")
    ax.set_title(f"pelvis height (fall bound: {FALL_DEVIATION_M * 1e3:g} mm)", fontsize=9)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    shown = most_moved(log.command, 8)
    colors = joint_colors(list(joints))
    for i in shown:
        ax2.plot(log.t_s, log.command[:, i], lw=0.9, color=colors[joints[i]], label=joints[i])
    ax2.set_xlabel("time (s)")
    ax2.set_ylabel("joint torque (N m)")
    ax2.set_title(f"torques of the {len(shown)} joints whose torque varied most", fontsize=9)
    ax2.legend(fontsize=7)
    ax2.grid(True, alpha=0.3)
    fig.suptitle(f"G1 standing, PD + gravity in torque mode (omega {params.omega_rad_s:g} rad/s, "
                 f"zeta {params.zeta:g}): max pelvis deviation {np.abs(dev).max() * 1e3:.2f} mm")
    fig.tight_layout()
    ctx.save_figure(fig, "g1_stand.png")


def prepare_track(params: TrackParams, robot: Robot | None = None) -> Work:
    """Load and weld the G1, convert to motors, plan the ruckig trajectory (no output yet)."""
    robot = position_to_motor(weld_base(robot or load_robot("g1", model_dir=params.model_dir), KEYFRAME))
    names = tuple(robot.joints)
    waypoints = track_waypoints(robot)
    limits = JointLimits.uniform(len(names), *TRACK_LIMITS)
    traj = plan_waypoints(waypoints, limits, robot.timestep_s, names)

    def work(ctx: RunContext) -> Outcome:
        sim = Simulator(robot)
        sim.reset(q=waypoints[0])
        controller = ComputedTorque(robot, gains_from_frequency(params.omega_rad_s, params.zeta))
        duration = params.duration_s or traj.duration_s + 0.2
        ctx.sections["inputs"] = {
            "duration_s": duration, "controller": "computed_torque",
            "limits": {"max_velocity_rad_s": TRACK_LIMITS[0], "max_acceleration_rad_s2": TRACK_LIMITS[1],
                       "max_jerk_rad_s3": TRACK_LIMITS[2]},
            "waypoints_rad": waypoints.tolist()}
        log = _loop(ctx, sim, controller, traj, duration, "N_m", "g1-track")
        err = log.reference - log.q[:, controller.joint_map.idx_q]
        return _tracking_outcome(ctx, "g1_track", log, err, controller, sim, params.max_rms_error_rad, {
            "trajectory_duration_s": traj.duration_s,
            "contacts_at_end": sim.contact_count,
        }, f"G1 welded base, computed torque (omega {params.omega_rad_s:g} rad/s, zeta {params.zeta:g})")

    return work


def _tracking_outcome(ctx: RunContext, name: str, log: RunLog, err: np.ndarray, controller: ControllerBase,
                      sim: Simulator, bound: float | None, extra: dict[str, Any], title: str,
                      plot_extra: tuple[str, np.ndarray] | None = None) -> Outcome:
    rms_by_joint = np.sqrt(np.mean(err**2, axis=0))
    rms = float(np.sqrt(np.mean(err**2)))
    ctx.values.update({
        "joint_rms_error_rad": rms,
        "joint_max_error_rad": float(np.abs(err).max()),
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
    _tracking_plot(ctx, name, log, controller.joints, err, f"{title}: joint RMS {rms:.3g} rad",
                   plot_extra)
    passed = bound is None or rms <= bound
    v = ctx.values
    return Outcome(passed, (
        f"{name.replace('_', '-')}: joint RMS error {rms:.3e} rad, max {v['joint_max_error_rad']:.3e} rad, "
        f"worst joint {v['worst_joint']} ({v['worst_joint_rms_error_rad']:.3e} rad RMS), "
        f"saturated cycles {v['saturated_cycles']}",
    ), None if bound is None else f"joint RMS error <= {bound:g} rad")


def prepare_arm_pd(params: ArmPDParams, robot: Robot | None = None) -> Work:
    """Load the G1 (position actuators) and plan the arm's trajectory (no output yet)."""
    robot = robot or load_robot("g1", model_dir=params.model_dir)
    traj = arm_trajectory(robot, params.side, robot.timestep_s)
    controller = PositionTargetPD(robot, traj.names, gravity_feedforward=params.gravity_feedforward)

    def work(ctx: RunContext) -> Outcome:
        sim = Simulator(robot)
        sim.reset(KEYFRAME)  # every actuator holds the keyframe's target; the arm's are overwritten
        z0 = sim.base_z_m
        duration = params.duration_s or traj.duration_s + 0.3
        ctx.sections["inputs"] = {
            "duration_s": duration, "controller": "position_pd",
            "limits": {"max_velocity_rad_s": ARM_LIMITS[0], "max_acceleration_rad_s2": ARM_LIMITS[1],
                       "max_jerk_rad_s3": ARM_LIMITS[2]},
            "actuator_kp_N_m_rad": controller.kp.tolist(), "actuator_kv_N_m_s_rad": controller.kv.tolist()}
        log = _loop(ctx, sim, controller, traj, duration, "rad", f"g1-arm-pd ({params.side} arm)")
        err = log.reference - log.q[:, controller.joint_map.idx_q]
        dz = log.q[:, 2] - z0
        return _tracking_outcome(ctx, "g1_arm_pd", log, err, controller, sim, params.max_rms_error_rad, {
            "arm": params.side,
            "pelvis_max_deviation_m": float(np.abs(dz).max()),
            "trajectory_duration_s": traj.duration_s,
        }, f"G1 {params.side} arm through the position actuators"
           + (" + gravity feed-forward" if params.gravity_feedforward else ""),
           ("pelvis height change (mm)", dz * 1e3))

    return work


#: The G1 jobs.
G1_STAND = Job("g1-stand", prepare_stand)
G1_TRACK = Job("g1-track", prepare_track)
G1_ARM_PD = Job("g1-arm-pd", prepare_arm_pd)
