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

Every job writes a CSV (one row per control cycle), a JSON execution report and a PNG, and
returns a result with ``summary()``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from mbctl.control.computed_torque import ComputedTorque
from mbctl.control.controller import joint_reference
from mbctl.control.exceptions import ControlError
from mbctl.control.gains import PDGains, gains_from_frequency
from mbctl.control.loop import RunLog, run
from mbctl.control.pd_gravity import PDGravity
from mbctl.control.position_pd import PositionTargetPD
from mbctl.jobs.output import new_figure, save_figure, write_columns_csv
from mbctl.planners.ruckig_planner import JointLimits, plan_ruckig, plan_waypoints
from mbctl.planners.trajectory import JointTrajectory
from mbctl.robots.edits import position_to_motor, weld_base
from mbctl.robots.model_pair import Robot
from mbctl.robots.registry import load_robot
from mbctl.sim.atomic import write_json_atomic
from mbctl.sim.report import execution_report
from mbctl.sim.simulator import Simulator

KEYFRAME = "stand"
LEG_WORDS = ("hip", "knee", "ankle")

#: Joint limits of the tracking trajectories: velocity [rad/s], acceleration [rad/s^2],
#: jerk [rad/s^3] (well inside the G1's actuator capabilities).
TRACK_LIMITS = (2.0, 10.0, 80.0)
ARM_LIMITS = (1.5, 6.0, 40.0)


@dataclass(frozen=True, eq=False)
class G1Result:
    """Outcome of a G1 job.

    Attributes:
        job: Job name.
        values: Scalar results (errors [rad], heights [m], counts) for the summary and report.
        files: Written files by role.
        log: The control loop's log.
    """

    job: str
    values: dict[str, Any]
    files: dict[str, Path]
    log: RunLog = field(repr=False)

    def summary(self) -> str:
        """Human-readable results with units (unit suffixes in the keys)."""
        lines = [f"{self.job}:"]
        for k, v in self.values.items():
            if isinstance(v, float):
                lines.append(f"  {k}: {v:.6g}")
            elif not isinstance(v, (dict, list)):
                lines.append(f"  {k}: {v}")
        lines.append("wrote " + ", ".join(str(p) for p in self.files.values()))
        return "\n".join(lines)


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


def _joint_columns(robot: Robot, log: RunLog, joints: tuple[str, ...], idx_q: np.ndarray,
                   command_label: str) -> dict[str, np.ndarray]:
    cols: dict[str, np.ndarray] = {"time_s": log.t_s}
    for i, j in enumerate(joints):
        if log.reference.shape[1] == len(joints):
            cols[f"q_ref_{j}_rad"] = log.reference[:, i]
        cols[f"q_{j}_rad"] = log.q[:, idx_q[i]]
    for i, j in enumerate(joints[: log.command.shape[1]]):
        cols[f"{command_label}_{j}"] = log.command[:, i]
    return cols


def g1_stand(
    duration_s: float = 10.0,
    output_dir: str | os.PathLike = "out/g1_stand",
    *,
    omega_rad_s: float = 10.0,
    zeta: float = 1.0,
    robot: Robot | None = None,
) -> G1Result:
    """Stand on the floor for ``duration_s`` under PD + gravity in torque mode.

    Args:
        duration_s: Simulated time [s].
        output_dir: Directory for ``g1_stand.csv``, ``g1_stand_report.json``, ``g1_stand.png``.
        omega_rad_s: Closed-loop natural frequency [rad/s].
        zeta: Damping ratio [-].
        robot: The G1 (default: ``load_robot("g1")``); converted to torque motors here.

    Raises:
        ModelNotFoundError: No G1 on this machine.
        SimulationDiverged: The plant diverged.
    """
    robot = position_to_motor(robot or load_robot("g1"))
    sim = Simulator(robot)
    sim.reset(KEYFRAME)
    q0 = robot.keyframe_q(KEYFRAME)
    probe = PDGravity(robot, PDGains(np.ones(1), np.ones(1)))
    inertia = stance_inertia(robot, q0, probe.joints)
    controller = PDGravity(robot, gains_from_frequency(omega_rad_s, zeta, inertia))
    reference = joint_reference(q0[controller.joint_map.idx_q])
    z0 = sim.base_z_m
    log = run(sim, controller, reference, duration_s)
    z = log.q[:, 2]
    z_end = sim.base_z_m
    dev = np.abs(np.append(z, z_end) - z0)
    joint_err = log.reference - log.q[:, controller.joint_map.idx_q]
    values = {
        "pelvis_z_keyframe_m": float(z0),
        "pelvis_z_min_m": float(min(z.min(), z_end)),
        "pelvis_z_max_m": float(max(z.max(), z_end)),
        "pelvis_z_final_m": float(z_end),
        "pelvis_max_deviation_m": float(dev.max()),
        "fell": bool(dev.max() > 0.02),
        "joint_rms_error_rad": float(np.sqrt(np.mean(joint_err**2))),
        "joint_max_error_rad": float(np.abs(joint_err).max()),
        "saturated_cycles": controller.saturation.saturated_cycles,
        "simulated_time_s": sim.time_s,
        "wall_time_s": log.wall_time_s,
    }
    out = Path(output_dir)
    cols = _joint_columns(robot, log, controller.joints, controller.joint_map.idx_q, "tau_N_m")
    cols["base_z_m"] = z
    files = {"csv": write_columns_csv(out / "g1_stand.csv", cols)}
    fig, axes = new_figure(1, 2, (12.0, 4.5))
    ax, ax2 = axes[0]
    ax.plot(log.t_s, (z - z0) * 1e3)
    ax.axhline(20, color="r", ls="--", lw=0.8)
    ax.axhline(-20, color="r", ls="--", lw=0.8, label="2 cm bound")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("pelvis height - keyframe [mm]")
    ax.legend()
    ax2.plot(log.t_s, log.command, lw=0.6)
    ax2.set_xlabel("time [s]")
    ax2.set_ylabel("joint torques [N m]")
    fig.tight_layout()
    files["plot"] = save_figure(fig, out / "g1_stand.png")
    report = execution_report(
        sim, "g1-stand",
        inputs={"duration_s": duration_s, "omega_rad_s": omega_rad_s, "zeta": zeta,
                "keyframe": KEYFRAME, "controller": "pd_gravity"},
        gains={"kp_N_m_rad": dict(zip(controller.joints, controller.gains.kp.tolist(), strict=True)),
               "kd_N_m_s_rad": dict(zip(controller.joints, controller.gains.kd.tolist(), strict=True)),
               "inertia_kg_m2": dict(zip(controller.joints, inertia.tolist(), strict=True))},
        values=values,
        controller_saturation=controller.saturation.summary(),
        outputs={k: str(v) for k, v in files.items()},
    )
    files["report"] = write_json_atomic(out / "g1_stand_report.json", report)
    return G1Result("g1-stand", values, files, log)


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


def g1_track(
    duration_s: float | None = None,
    output_dir: str | os.PathLike = "out/g1_track",
    *,
    omega_rad_s: float = 40.0,
    zeta: float = 1.0,
    robot: Robot | None = None,
) -> G1Result:
    """Computed torque on the welded-base G1 along ruckig trajectories (arms, legs, waist).

    Args:
        duration_s: Simulated time [s]; None runs the whole trajectory plus 0.2 s.
        output_dir: Directory for ``g1_track.csv``, ``g1_track_report.json``, ``g1_track.png``.
        omega_rad_s: Closed-loop natural frequency [rad/s] (per unit inertia).
        zeta: Damping ratio [-].
        robot: The floating-base G1 (default: ``load_robot("g1")``); welded and converted here.

    Raises:
        ModelNotFoundError: No G1 on this machine.
        SimulationDiverged: The plant diverged.
    """
    robot = position_to_motor(weld_base(robot or load_robot("g1"), KEYFRAME))
    sim = Simulator(robot)
    names = tuple(robot.joints)
    waypoints = track_waypoints(robot)
    limits = JointLimits.uniform(len(names), *TRACK_LIMITS)
    traj = plan_waypoints(waypoints, limits, sim.control_period_s, names)
    sim.reset(q=waypoints[0])
    controller = ComputedTorque(robot, gains_from_frequency(omega_rad_s, zeta))
    duration = duration_s or traj.duration_s + 0.2
    log = run(sim, controller, traj, duration)
    idx_q = controller.joint_map.idx_q
    err = log.reference - log.q[:, idx_q]
    rms_by_joint = np.sqrt(np.mean(err**2, axis=0))
    values = {
        "joint_rms_error_rad": float(np.sqrt(np.mean(err**2))),
        "joint_max_error_rad": float(np.abs(err).max()),
        "worst_joint": controller.joints[int(np.argmax(rms_by_joint))],
        "worst_joint_rms_error_rad": float(rms_by_joint.max()),
        "trajectory_duration_s": traj.duration_s,
        "saturated_cycles": controller.saturation.saturated_cycles,
        "contacts_at_end": sim.contact_count,
        "simulated_time_s": sim.time_s,
        "wall_time_s": log.wall_time_s,
        "rms_error_by_joint_rad": dict(zip(controller.joints, rms_by_joint.tolist(), strict=True)),
    }
    out = Path(output_dir)
    files = {"csv": write_columns_csv(
        out / "g1_track.csv", _joint_columns(robot, log, controller.joints, idx_q, "tau_N_m"))}
    files["plot"] = _plot_tracking(out / "g1_track.png", log, err, controller.joints,
                                   "G1 welded base, computed torque")
    report = execution_report(
        sim, "g1-track",
        inputs={"duration_s": duration, "omega_rad_s": omega_rad_s, "zeta": zeta,
                "limits": {"max_velocity_rad_s": TRACK_LIMITS[0],
                           "max_acceleration_rad_s2": TRACK_LIMITS[1],
                           "max_jerk_rad_s3": TRACK_LIMITS[2]},
                "waypoints_rad": waypoints.tolist(), "controller": "computed_torque"},
        values=values,
        controller_saturation=controller.saturation.summary(),
        outputs={k: str(v) for k, v in files.items()},
    )
    files["report"] = write_json_atomic(out / "g1_track_report.json", report)
    return G1Result("g1-track", values, files, log)


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


def g1_arm_pd(
    duration_s: float | None = None,
    output_dir: str | os.PathLike = "out/g1_arm_pd",
    *,
    side: str = "left",
    gravity_feedforward: bool = True,
    robot: Robot | None = None,
) -> G1Result:
    """One arm follows a ruckig trajectory through the Menagerie position actuators.

    Args:
        duration_s: Simulated time [s]; None runs the whole trajectory plus 0.3 s.
        output_dir: Directory for ``g1_arm_pd.csv``, ``g1_arm_pd_report.json``, ``g1_arm_pd.png``.
        side: "left" or "right" arm.
        gravity_feedforward: Offset the targets by ``g(q) / kp``.
        robot: The G1 with position actuators (default: ``load_robot("g1")``).

    Raises:
        ControlError: An unknown side.
        ModelNotFoundError: No G1 on this machine.
        SimulationDiverged: The plant diverged.
    """
    if side not in ("left", "right"):
        raise ControlError(f"side must be 'left' or 'right'; got {side!r}")
    robot = robot or load_robot("g1")
    sim = Simulator(robot)
    sim.reset(KEYFRAME)  # every actuator holds the keyframe's target; the arm's are overwritten
    traj = arm_trajectory(robot, side, sim.control_period_s)
    controller = PositionTargetPD(robot, traj.names, gravity_feedforward=gravity_feedforward)
    z0 = sim.base_z_m
    duration = duration_s or traj.duration_s + 0.3
    log = run(sim, controller, traj, duration)
    idx_q = controller.joint_map.idx_q
    err = log.reference - log.q[:, idx_q]
    z = log.q[:, 2]
    values = {
        "arm": side,
        "joint_rms_error_rad": float(np.sqrt(np.mean(err**2))),
        "joint_max_error_rad": float(np.abs(err).max()),
        "final_max_error_rad": float(np.abs(err[-1]).max()),
        "pelvis_max_deviation_m": float(np.abs(z - z0).max()),
        "targets_clipped_cycles": controller.saturation.saturated_cycles,
        "trajectory_duration_s": traj.duration_s,
        "simulated_time_s": sim.time_s,
        "wall_time_s": log.wall_time_s,
    }
    out = Path(output_dir)
    cols = _joint_columns(robot, log, controller.joints, idx_q, "target_rad")
    cols["base_z_m"] = z
    files = {"csv": write_columns_csv(out / "g1_arm_pd.csv", cols)}
    files["plot"] = _plot_tracking(out / "g1_arm_pd.png", log, err, controller.joints,
                                   f"G1 {side} arm, PD through position actuators")
    report = execution_report(
        sim, "g1-arm-pd",
        inputs={"duration_s": duration, "side": side, "gravity_feedforward": gravity_feedforward,
                "limits": {"max_velocity_rad_s": ARM_LIMITS[0],
                           "max_acceleration_rad_s2": ARM_LIMITS[1],
                           "max_jerk_rad_s3": ARM_LIMITS[2]},
                "actuator_kp_N_m_rad": controller.kp.tolist(),
                "actuator_kv_N_m_s_rad": controller.kv.tolist(),
                "controller": "position_pd"},
        values=values,
        controller_saturation=controller.saturation.summary(),
        outputs={k: str(v) for k, v in files.items()},
    )
    files["report"] = write_json_atomic(out / "g1_arm_pd_report.json", report)
    return G1Result("g1-arm-pd", values, files, log)


def _plot_tracking(path: Path, log: RunLog, err: np.ndarray, joints: tuple[str, ...],
                   title: str) -> Path:
    fig, axes = new_figure(1, 2, (13.0, 4.8))
    ax, ax2 = axes[0]
    ax.plot(log.t_s, log.reference, lw=0.8)
    ax.set_prop_cycle(None)
    ax.plot(log.t_s, log.reference - err, lw=0.8, ls="--")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("joint angle [rad] (solid: reference, dashed: measured)")
    ax.set_title(title)
    rms = np.sqrt(np.mean(err**2, axis=0))
    for i in np.argsort(rms)[::-1][:6]:
        ax2.plot(log.t_s, err[:, i] * 1e3, lw=0.8, label=joints[i])
    ax2.set_xlabel("time [s]")
    ax2.set_ylabel("joint error [mrad] (6 worst joints)")
    ax2.legend(fontsize=7)
    fig.tight_layout()
    return save_figure(fig, path)
