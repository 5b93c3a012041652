"""``mbctl g1-wbc SCENARIO``: whole-body inverse dynamics on the floating-base G1, in torque mode.

The Menagerie position actuators become torque motors (force ranges kept); the
:class:`~mbctl.control.wbc.WholeBodyController` (CoM, pelvis and torso orientation, posture,
angular-momentum damping, and per scenario a swing foot or the palms) computes the torques each
control cycle from the Pinocchio model; MuJoCo executes them. Scenarios:

``stand``    10 s, CoM over the middle of the feet.
``squat``    CoM height ``z0 - A (1 - cos 2 pi f t)``, A = 0.08 m, f = 0.5 Hz, 10 s.
``one-foot`` CoM over the left sole, right foot released (force ramp), lifted 5 cm, held 5 s,
             put back, CoM back to the middle.
``reach``    both palms 0.20 m forward and back (min-jerk) while balancing.
``push``     a horizontal force on the pelvis held 0.1 s (``--impulse`` N s) from 8 directions,
             2 s apart (or one, ``--direction DEG``), no stepping.

Checked in the plant (MuJoCo), not in the model: the CoM (``subtree_com``), the feet (site
positions), the contact forces (``mj_contactForce`` on the foot geoms), and whether anything
other than the feet touches the floor. Foot slip is the horizontal drift of a supporting foot
(full contact weight, at least 10 % of m g measured on it) from where it last started to
support. The report's values: ``fell``, ``com_error_rms_m``,
``max_foot_slip_m``, ``contact_force_rel_error``, ``controller_time_median_us``,
``qp_solve_time_median_us``, ``torque_saturation_steps`` (and per-foot contact errors).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np
import pinocchio as pin

from mbctl.control.exceptions import WBCSetupError
from mbctl.control.wbc import (
    AngularMomentumDamping,
    ComAcceleration,
    FrameOrientationAcceleration,
    FramePoseAcceleration,
    FramePositionAcceleration,
    PostureAcceleration,
    TaskGains,
    WholeBodyController,
    foot_contact_from_model,
)
from mbctl.jobs.demo import scale_masses
from mbctl.jobs.recording import q_columns
from mbctl.jobs.robot_constants import FEET, KEYFRAME, PALM_SITES, PELVIS, with_palm_sites
from mbctl.jobs.runner import Job, Outcome, RunContext, Work
from mbctl.robots.edits import position_to_motor
from mbctl.robots.interface import RobotState
from mbctl.robots.model_pair import Robot
from mbctl.robots.registry import load_robot
from mbctl.sim.contacts import measure_contacts, touching
from mbctl.sim.perturb import Push, PushSchedule
from mbctl.sim.simulator import Simulator

SCENARIOS = ("stand", "squat", "one-foot", "reach", "push")
#: Default simulated time [s] per scenario.
DEFAULT_DURATION_S = {"stand": 10.0, "squat": 10.0, "one-foot": 14.0, "reach": 8.0, "push": 17.0}
#: Pelvis height [m] below which the robot has fallen.
FALL_HEIGHT_M = 0.5
SQUAT_AMPLITUDE_M = 0.08
SQUAT_FREQUENCY_HZ = 0.5
LIFT_HEIGHT_M = 0.05
REACH_M = 0.20
PUSH_HOLD_S = 0.1
PUSH_PERIOD_S = 2.0
TORSO = "torso_link"
#: A foot supports the robot (its slip counts) when MuJoCo measures at least this fraction of
#: m g on it at full contact weight.
SUPPORT_FRACTION = 0.1


@dataclass(frozen=True)
class WBCParams:
    """Parameters of ``mbctl g1-wbc`` (field names are the CLI options).

    Attributes:
        scenario: One of :data:`SCENARIOS`.
        duration: Simulated time [s] (None: the scenario's default).
        impulse: Push impulse [N s] (push scenario).
        direction: Push direction [deg] in the world x-y plane (0 = +x, the robot's front; 90 =
            +y, its left); None: eight directions 45 deg apart, 2 s apart.
        model_error: The controller model's link masses and inertias off by this [%].
        model_dir: Explicit G1 folder (else MENAGERIE_ROOT, the package cache).
    """

    scenario: str = "stand"
    duration: float | None = None
    impulse: float = 10.0
    direction: float | None = None
    model_error: float = 0.0
    model_dir: str | None = None

    def __post_init__(self) -> None:
        if self.scenario not in SCENARIOS:
            raise WBCSetupError(f"unknown scenario {self.scenario!r}; choose one of {', '.join(SCENARIOS)}")
        if self.duration is not None and not (np.isfinite(self.duration) and self.duration > 0):
            raise WBCSetupError(f"duration must be a positive number of seconds; got {self.duration}")
        if not (np.isfinite(self.impulse) and self.impulse >= 0):
            raise WBCSetupError(f"impulse must be a finite impulse >= 0 N s; got {self.impulse}")
        if self.direction is not None and not np.isfinite(self.direction):
            raise WBCSetupError(f"direction must be a finite angle in degrees; got {self.direction}")
        if not (np.isfinite(self.model_error) and -50 < self.model_error < 100):
            raise WBCSetupError(f"model_error must be a percentage in (-50, 100); got {self.model_error}")

    @property
    def duration_s(self) -> float:
        """The simulated time [s]."""
        if self.duration is not None:
            return self.duration
        if self.scenario == "push" and self.direction is not None:
            return 1.0 + PUSH_PERIOD_S
        return DEFAULT_DURATION_S[self.scenario]


def _min_jerk(s: float) -> tuple[float, float, float]:
    """Min-jerk blend and its first two derivatives at phase s in [0, 1] (per unit phase)."""
    s = min(max(s, 0.0), 1.0)
    return (10 * s**3 - 15 * s**4 + 6 * s**5, 30 * s**2 - 60 * s**3 + 30 * s**4,
            60 * s - 180 * s**2 + 120 * s**3)


def _blend(a: np.ndarray, b: np.ndarray, t: float, t0: float, T: float) -> tuple[np.ndarray, np.ndarray,
                                                                                   np.ndarray]:
    """Min-jerk from ``a`` to ``b`` over [t0, t0 + T]: position, velocity, acceleration."""
    s, ds, dds = _min_jerk((t - t0) / T)
    if t < t0 or t > t0 + T:
        ds = dds = 0.0
    d = b - a
    return a + s * d, d * ds / T, d * dds / T**2


@dataclass
class G1WholeBody:
    """The G1 whole-body controller with the standing task set (and optional swing/hand tasks)."""

    robot: Robot
    controller: WholeBodyController
    com: ComAcceleration
    pelvis: FrameOrientationAcceleration
    torso: FrameOrientationAcceleration
    posture: PostureAcceleration
    momentum: AngularMomentumDamping
    extra: dict[str, Any] = field(default_factory=dict)

    def hold(self, state: RobotState) -> None:
        """Both feet in contact where they are, and every task's reference at ``state``'s values."""
        self.controller.reset_contacts(state)
        s = self.controller.state
        self.com.set_reference(s.com().copy())
        self.pelvis.set_reference(s.frame_pose(self.pelvis.fid))
        self.torso.set_reference(s.frame_pose(self.torso.fid))
        self.posture.set_reference(state.q)


def g1_whole_body(robot: Robot, pin_model: pin.Model | None = None) -> G1WholeBody:
    """The controller and its standing task set on ``robot`` (a torque-mode G1 with palm sites).

    Task weights and gains (weight, omega [rad/s], zeta): CoM (10, 10, 1), pelvis orientation
    (5, 10, 1), torso orientation (2, 10, 1), posture (0.05, 10, 1), angular momentum (0.2, 4, 1).
    """
    feet = [foot_contact_from_model(robot, f) for f in FEET]
    ctrl = WholeBodyController(robot, feet, pin_model=pin_model)
    m = ctrl.model
    wb = G1WholeBody(
        robot, ctrl,
        com=ComAcceleration(TaskGains(10.0, 10.0, 1.0)),
        pelvis=FrameOrientationAcceleration(PELVIS, m, TaskGains(5.0, 10.0, 1.0)),
        torso=FrameOrientationAcceleration(TORSO, m, TaskGains(2.0, 10.0, 1.0)),
        posture=PostureAcceleration(m, ctrl.joints.idx_v, TaskGains(0.05, 10.0, 1.0)),
        momentum=AngularMomentumDamping(TaskGains(0.2, 4.0, 1.0)),
    )
    for task in (wb.com, wb.pelvis, wb.torso, wb.posture, wb.momentum):
        ctrl.add_task(task)
    return wb


#: Leg joints of the crouched start [rad]: the keyframe's straight knees are a singularity of
#: the CoM height (its Jacobian row vanishes), so every scenario starts with bent knees.
CROUCH_RAD = {"hip_pitch": -0.3, "knee": 0.6, "ankle_pitch": -0.3}


def crouched_start(robot: Robot) -> np.ndarray:
    """The ``stand`` keyframe with bent knees (:data:`CROUCH_RAD`), feet flat where they were.

    The base moves down and back by the feet's displacement, so the soles keep their keyframe
    pose (hip + knee + ankle pitch = 0 keeps them flat).
    """
    model = robot.pin_model
    data = model.createData()
    q = robot.keyframe_q(KEYFRAME).copy()
    for side in ("left", "right"):
        for joint, value in CROUCH_RAD.items():
            q[robot.joint(f"{side}_{joint}_joint").idx_q] = value
    feet = [model.getFrameId(f) for f in FEET]
    pin.framesForwardKinematics(model, data, robot.keyframe_q(KEYFRAME))
    before = np.mean([data.oMf[f].translation for f in feet], axis=0)
    pin.framesForwardKinematics(model, data, q)
    after = np.mean([data.oMf[f].translation for f in feet], axis=0)
    q[:3] += before - after
    return q


def _sole_center_W(wb: G1WholeBody, foot: str) -> np.ndarray:
    cs = wb.controller.contacts[foot]
    X = wb.controller.state.frame_pose(cs.fid)
    return X.act(cs.contact.points_F.mean(axis=0))


Update = Callable[[float], None]


def _scenario(params: WBCParams, wb: G1WholeBody, sim: Simulator) -> tuple[Update, PushSchedule | None]:
    """Set the initial references; return the per-cycle reference update and the pushes."""
    ctrl, s = wb.controller, wb.controller.state
    c0 = s.com().copy()
    mid = 0.5 * (_sole_center_W(wb, FEET[0]) + _sole_center_W(wb, FEET[1]))
    home = np.array([mid[0], mid[1], c0[2]])
    wb.pelvis.set_reference(pin.SE3(np.eye(3), np.zeros(3)))
    wb.torso.set_reference(pin.SE3(np.eye(3), np.zeros(3)))
    wb.posture.set_reference(s.q.copy())
    pushes = None

    def hold_com(t: float, start: np.ndarray = c0) -> None:
        p, v, a = _blend(start, home, t, 0.0, 1.0)
        wb.com.set_reference(p, v, a)

    update: Update = hold_com
    if params.scenario == "squat":
        w = 2 * np.pi * SQUAT_FREQUENCY_HZ
        A = SQUAT_AMPLITUDE_M

        def update(t: float) -> None:
            p, v, a = _blend(c0, home, t, 0.0, 1.0)  # x, y over the feet
            wb.com.set_reference(p - [0, 0, A * (1 - np.cos(w * t))], v - [0, 0, A * w * np.sin(w * t)],
                                 a - [0, 0, A * w * w * np.cos(w * t)])
    elif params.scenario == "one-foot":
        left = _sole_center_W(wb, FEET[0])
        over_left = np.array([left[0], left[1], c0[2]])
        right, swing = FEET[1], FramePoseAcceleration(FEET[1], ctrl.model, TaskGains(10.0, 20.0, 1.0))
        wb.extra["swing"] = swing
        # phases [s]: shift 0-2, release (force ramp) from 2, lift 2.5-3.5, hold 3.5-8.5, lower
        # 8.5-9.5, touch down and load from 9.5, shift back 10-12
        poses: dict[str, pin.SE3] = {}

        def update(t: float) -> None:
            if t < 10.0:
                p, v, a = _blend(c0, over_left, t, 0.0, 2.0)
            else:
                p, v, a = _blend(over_left, home, t, 10.0, 2.0)
            wb.com.set_reference(p, v, a)
            if t >= 2.0 and "down" not in poses and ctrl.contacts[right].target_weight > 0:
                ctrl.release(right)
            if ctrl.contact_released(right) and "down" not in poses:
                # the swing task starts where the foot is, at rest: no acceleration jump
                poses["down"] = pin.SE3(s.frame_pose(ctrl.contacts[right].fid))
                swing.set_reference(poses["down"])
                ctrl.add_task(swing)
            if swing in ctrl.tasks:
                down = poses["down"].translation
                up = down + [0, 0, LIFT_HEIGHT_M]
                pf, vf, af = _blend(down, up, t, 2.5, 1.0) if t < 8.5 else _blend(up, down, t, 8.5, 1.0)
                swing.set_reference(pin.SE3(poses["down"].rotation, pf), vf, af)
                if t >= 9.5:
                    ctrl.remove_task(swing)
                    ctrl.touch_down(right)
    elif params.scenario == "reach":
        hands = {}
        for site in PALM_SITES:
            task = FramePositionAcceleration(site, ctrl.model, TaskGains(5.0, 10.0, 1.0))
            p0 = s.frame_pose(task.fid).translation.copy()
            task.set_reference(p0)
            ctrl.add_task(task)
            hands[site] = (task, p0)
        wb.extra["hands"] = hands

        def update(t: float) -> None:
            hold_com(t)
            for task, p0 in hands.values():
                p1 = p0 + [REACH_M, 0.0, 0.0]
                p, v, a = _blend(p0, p1, t, 1.0, 2.5) if t < 4.0 else _blend(p1, p0, t, 4.5, 2.5)
                task.set_reference(p, v, a)
    elif params.scenario == "push":
        force = params.impulse / PUSH_HOLD_S
        angles = [k * 45.0 for k in range(8)] if params.direction is None else [params.direction]
        pushes = PushSchedule(sim.model, [
            Push(PELVIS, (force * np.cos(np.radians(a)), force * np.sin(np.radians(a)), 0.0),
                 1.0 + PUSH_PERIOD_S * k, PUSH_HOLD_S) for k, a in enumerate(angles)])
    return update, pushes


def prepare(params: WBCParams, robot: Robot | None = None) -> Work:
    """Load the G1 (or take ``robot``, a Menagerie G1), in torque mode with palm sites (no output yet)."""
    robot = position_to_motor(with_palm_sites(robot or load_robot("g1", model_dir=params.model_dir)))
    factor = 1.0 + params.model_error / 100.0
    pin_model = scale_masses(robot.pin_model, factor) if params.model_error else None

    def work(ctx: RunContext) -> Outcome:
        return _run(ctx, params, robot, pin_model)

    return work


def _foot_geoms(wb: G1WholeBody) -> dict[str, tuple[int, ...]]:
    return {name: cs.contact.geoms for name, cs in wb.controller.contacts.items()}


def _run(ctx: RunContext, params: WBCParams, robot: Robot, pin_model: pin.Model | None) -> Outcome:
    sim = ctx.attach(Simulator(robot), contact_forces=True)
    sim.reset(KEYFRAME)
    sim.set_state(crouched_start(robot), np.zeros(robot.pin_model.nv))
    wb = g1_whole_body(robot, pin_model)
    ctrl = wb.controller
    state = sim.read_state()
    ctrl.reset_contacts(state)
    update, pushes = _scenario(params, wb, sim)
    m, d = sim.model, sim.data
    pelvis_id = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, PELVIS)
    floor = [g for g in range(m.ngeom) if m.geom_bodyid[g] == 0]
    foot_geoms = _foot_geoms(wb)
    allowed = [g for gs in foot_geoms.values() for g in gs]
    foot_sites = {f: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, f) for f in FEET}
    mg = ctrl.state.mass * 9.81 if pin_model is None else float(
        sum(i.mass for i in robot.pin_model.inertias)) * 9.81
    dt = sim.control_period_s
    n = int(round(params.duration_s / dt))
    header = ["time_s", "com_ref_x_m", "com_ref_y_m", "com_ref_z_m", "com_x_m", "com_y_m", "com_z_m",
              "base_z_m", "push_fx_N", "push_fy_N"]
    for f in FEET:
        header += [f"{f}_fz_qp_N", f"{f}_ft_qp_N", f"{f}_cop_x_qp_m", f"{f}_cop_y_qp_m",
                   f"{f}_fz_mj_N", f"{f}_ft_mj_N", f"{f}_cop_x_mj_m", f"{f}_cop_y_mj_m", f"{f}_slip_m"]
    header += [f"tau_{a}_N_m" for a in ctrl.joints.actuators] + q_columns(robot)
    csv = ctx.open_csv(header)
    ctx.sections["inputs"] = {"scenario": params.scenario, "keyframe": KEYFRAME,
                              "controller": "whole-body inverse dynamics QP (control/wbc)",
                              "model_error_pct": params.model_error,
                              "tasks": [t.name for t in ctrl.tasks]}
    ctx.progress.start(n, f"g1-wbc {params.scenario}")
    log: dict[str, list[Any]] = {k: [] for k in ("t", "com_ref", "com", "fz_qp", "fz_mj", "ft_qp", "ft_mj",
                                                  "cop_qp", "cop_mj", "stance", "ctrl_us", "qp_us",
                                                  "slip", "z")}
    sat = 0
    feet_home = {f: d.site_xpos[foot_sites[f]].copy() for f in FEET}
    fell_reason = None
    for k in range(n):
        t = sim.time_s
        update(t)
        state = sim.read_state()
        command = ctrl.compute(state, dt_s=dt)
        sol = ctrl.solution
        push = pushes.apply(d) if pushes is not None else np.zeros(3)
        sim.step(command)
        meas = measure_contacts(m, d, foot_geoms)  # the forces of the step just taken
        mujoco.mj_forward(m, d)
        com_mj = d.subtree_com[pelvis_id].copy()
        row = [t, *wb.com.p_ref, *com_mj, float(d.qpos[2]), push[0], push[1]]
        fz_qp = fz_mj = 0.0
        stance = all(cs.active and cs.weight == 1.0 for cs in ctrl.contacts.values())
        slips = []
        for f in FEET:
            F = sol.forces_W[f].sum(0)
            cop = sol.cop_W[f]
            mc = meas[f]
            cs = ctrl.contacts[f]
            supporting = cs.active and cs.weight == 1.0 and mc.normal_n >= SUPPORT_FRACTION * mg
            if supporting:
                slip = float(np.linalg.norm((d.site_xpos[foot_sites[f]] - feet_home[f])[:2]))
                slips.append(slip)
            else:  # unloaded or swinging: slip counts from when it supports again
                slip = 0.0
                feet_home[f] = d.site_xpos[foot_sites[f]].copy()
            row += [F[2], float(np.hypot(F[0], F[1])), cop[0], cop[1], mc.normal_n, mc.tangential_n,
                    mc.cop_W[0], mc.cop_W[1], slip]
            fz_qp += F[2]
            fz_mj += mc.normal_n
            log["cop_qp"].append(cop[:2])
            log["cop_mj"].append(mc.cop_W[:2])
        at_limit = np.isclose(command.values, ctrl.tau_low) | np.isclose(command.values, ctrl.tau_high)
        sat += int(np.any(at_limit))
        row += list(command.values) + list(state.q)
        csv.write(row)
        log["t"].append(t)
        log["com_ref"].append(wb.com.p_ref)
        log["com"].append(com_mj)
        log["fz_qp"].append([sol.forces_W[f][:, 2].sum() for f in FEET])
        log["fz_mj"].append([meas[f].normal_n for f in FEET])
        log["ft_qp"].append([float(np.hypot(*sol.forces_W[f][:, :2].sum(0))) for f in FEET])
        log["ft_mj"].append([meas[f].tangential_n for f in FEET])
        log["stance"].append(stance)
        log["ctrl_us"].append(sol.controller_time_s * 1e6)
        log["qp_us"].append(sol.qp_time_s * 1e6)
        log["slip"].append(max(slips) if slips else 0.0)
        log["z"].append(float(d.qpos[2]))
        ctx.progress.advance()
        others = touching(m, d, floor, allowed)
        if d.qpos[2] < FALL_HEIGHT_M or others:
            fell_reason = (f"pelvis at {d.qpos[2]:.3f} m" if d.qpos[2] < FALL_HEIGHT_M
                           else f"{', '.join(others)} touched the floor") + f" at t={sim.time_s:.2f} s"
            break
        if k % 50 == 0:
            _values(ctx, log, mg, sat, fell_reason)
    values = _values(ctx, log, mg, sat, fell_reason)
    from mbctl.jobs.wbc_plots import wbc_plots

    wbc_plots(ctx, log, params, values)
    fell = values["fell"]
    ok = not fell
    bounds = []
    if params.scenario == "squat":
        ok = ok and values["com_error_rms_m"] < 5e-3 and values["max_foot_slip_m"] < 1e-3
        bounds.append("CoM RMS < 5 mm, foot slip < 1 mm")
    bounds.append("did not fall")
    summary = (
        f"g1-wbc {params.scenario} {sim.time_s:.2f} s: {f'FELL ({fell_reason})' if fell else 'stood'}; "
        f"CoM RMS {values['com_error_rms_m'] * 1e3:.2f} mm, max foot slip "
        f"{values['max_foot_slip_m'] * 1e3:.3f} mm, contact force error "
        f"{values['contact_force_rel_error'] * 100:.2f} % of m g, controller "
        f"{values['controller_time_median_us']:.0f} us (QP "
        f"{values['qp_solve_time_median_us']:.0f} us) median, "
        f"saturated steps {values['torque_saturation_steps']}",)
    return Outcome(ok, summary, "; ".join(bounds))


def _values(ctx: RunContext, log: dict[str, list[Any]], mg: float, sat: int, fell_reason: str | None
            ) -> dict[str, Any]:
    """Fill ``ctx.values`` from the log so far (an interrupted run keeps them)."""
    if not log["t"]:
        return ctx.values
    com_err = np.asarray(log["com"]) - np.asarray(log["com_ref"])
    stance = np.asarray(log["stance"])
    fz_qp, fz_mj = np.asarray(log["fz_qp"]), np.asarray(log["fz_mj"])
    rel = np.abs(fz_qp.sum(1) - fz_mj.sum(1)) / mg
    per_foot = np.abs(fz_qp - fz_mj) / mg
    ctx.values.update({
        "fell": fell_reason is not None,
        "com_error_rms_m": float(np.sqrt(np.mean(np.sum(com_err**2, axis=1)))),
        "max_foot_slip_m": float(np.max(log["slip"])),
        "contact_force_rel_error": float(np.median(rel[stance])) if stance.any() else float("nan"),
        "controller_time_median_us": float(np.median(log["ctrl_us"])),
        "qp_solve_time_median_us": float(np.median(log["qp_us"])),
        "torque_saturation_steps": int(sat),
        "contact_normal_rel_error_per_foot": {f: float(np.median(per_foot[stance, i])) if stance.any()
                                              else float("nan") for i, f in enumerate(FEET)},
        "fall_reason": fell_reason,
        "pelvis_z_min_m": float(np.min(log["z"])),
    })
    return ctx.values


G1_WBC = Job("g1-wbc", prepare)
