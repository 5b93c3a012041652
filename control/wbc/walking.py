"""Walking on the whole-body QP: footsteps, a DCM plan, swing feet and contact switches, for any biped.

One :class:`WalkingController` is a :class:`~mbctl.control.controller.Controller` (``compute(state)
-> torque Command``, ``reset()``) that runs against any robot interface, in-process or over DDS.
Each cycle:

1. **Gait phase** (:mod:`mbctl.control.wbc.gait`): the start (both feet, the weight shifts), then
   single support (one foot swings) and double support, alternating. A foot leaves with a force
   ramp (its release starts ``ramp_s`` before the double support ends, so it is free when single
   support begins) and lands with one (constrained where it touched down, its force ramping up).
   The options are :class:`~mbctl.control.wbc.walking_config.WalkingConfig`'s. Touchdown is
   detected from contact: ``contact_force(foot)`` (the plant's contact sensor in sim)
   above ``touchdown_force_n``, else from kinematics (the sole within
   ``touchdown_height_m`` of the ground, as over DDS where the base comes from
   the estimator). An early touchdown (after ``early_touchdown_phase`` of the
   swing) ends the swing there; a late one lowers the foot further at
   ``late_descent_m_s``, down to ``late_extension_m`` below
   the footstep, and lands it there at the latest.
2. **Footsteps** (:mod:`mbctl.planners.footsteps`): the swing foot's footstep and the next
   ``preview_steps`` from the velocity command (clamped to the model's limits; the clamp is
   reported), which may change every cycle and is followed at ``max_acceleration``; the footsteps'
   yaw rate also corrects the heading error (the heading reference integrates the yaw-rate
   command), and their speed the measured speed's error over the last step (the speed loop). The
   swing footstep follows the command until ``retarget_until_phase`` of the swing
   (``pushed_retarget_until_phase`` while the DCM was off its plan by ``cmp_outside_after_m``), moved by the
   step-adaptation QP when the measured DCM leaves its tube (:mod:`mbctl.control.wbc.step_adaptation`);
   where a limit holds that footstep far short sideways (a pushed one also backward:
   ``pushed_timing_along``), the QP shortens the swing as well
   (``timing_adaptation``: no quicker than ``min_single_support_s``, ``min_swing_left_s`` from now,
   nor than the foot's way to its footstep at ``max_swing_speed_m_s``), and the swing path is re-timed.
   The footsteps are planned every ``replan_period_s`` and at every contact event; steps 3 and 4
   run every cycle, on the plan in force.
3. **DCM** (:mod:`mbctl.planners.dcm`): the plan through the footsteps' sole centres, the measured
   DCM ``xi = x + xdot / omega`` (CoM from the state), the feedback law's desired CMP, clamped into
   the support polygon (the active feet's contact points) less ``cmp_margin_m``; with the DCM more
   than ``cmp_outside_after_m`` from its plan (a push), grown by ``cmp_outside_m`` instead (the
   angular momentum makes the difference: the hip strategy),
   and the CoM task's acceleration ``xddot = omega^2 (x - p_cmp)`` (horizontal; the height is a
   PD on ``z_c`` above the ground).
4. **Tasks**: the swing foot as a pose task (:mod:`mbctl.planners.swing`: lift, land at rest),
   pelvis and torso orientation (upright, heading between the feet), angular-momentum damping
   and the posture (the arms hang), from the standing task set
   (:func:`~mbctl.control.wbc.standing.standing_controller`); then the QP.

Nothing here names a robot: feet, base and torso frames and the reference configuration are
parameters (a robot's come from its facts module in robots/, given by the jobs).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import pinocchio as pin

from mbctl.control.exceptions import WBCSetupError
from mbctl.control.wbc._walking_plan import WalkPlans
from mbctl.control.wbc.config import WBCConfig
from mbctl.control.wbc.contacts import foot_contact_from_model
from mbctl.control.wbc.gait import DOUBLE, Gait, GaitEvent
from mbctl.control.wbc.speed_loop import SpeedLoop
from mbctl.control.wbc.standing import Standing, standing_controller
from mbctl.control.wbc.step_adaptation import StepAdaptation, StepAdapter, StepTiming, dcm_tube
from mbctl.control.wbc.swing_task import SwingFootTask
from mbctl.control.wbc.walking_config import WalkingConfig
from mbctl.planners.dcm import ConvexPolygon, dcm_omega
from mbctl.planners.footsteps import (
    CommandClamp,
    Footstep,
    FootstepPlanner,
    VelocityCommand,
    step_limits_from_model,
)
from mbctl.robots.commands import Command
from mbctl.robots.interface import RobotState
from mbctl.robots.model_pair import Robot

#: ``contact_force(foot) -> normal force [N]`` measured on a foot (None: not measured).
ContactForce = Callable[[str], "float | None"]

#: The swing is re-timed when the adapted touchdown moves by more than this [s].
RETIME_TOLERANCE_S = 0.002



@dataclass
class WalkingStatus:
    """What the last cycle planned and measured (horizontal quantities in W).

    Attributes:
        time_s: The state's time [s].
        phase: "start", "single" or "double".
        stance: The supporting foot ("both" outside single support).
        dcm: Measured DCM (2,) [m].
        dcm_ref: The plan's DCM (2,) [m].
        zmp_ref: The plan's VRP (the ZMP reference) (2,) [m].
        zmp_ref_margin_m: Its margin in the support polygon [m] (> 0 inside).
        cmp: Desired CMP from the feedback law, before the clamp (2,) [m].
        cmp_margin_m: Its margin in the support polygon [m] (< 0: outside; below -cmp_outside_m the
            clamp moved it).
        cmp_clamped: The CMP given to the CoM (2,) [m].
        com_acceleration: The CoM acceleration asked of the QP (3,) [m/s^2].
        footsteps: The footsteps planned (the swing foot's first).
        event: What happened this cycle (a release, a lift-off, a touchdown), or None.
        adaptation: The last step adaptation (None before the first single support).
    """

    time_s: float = 0.0
    phase: str = "start"
    stance: str = "both"
    dcm: np.ndarray = field(default_factory=lambda: np.zeros(2))
    dcm_ref: np.ndarray = field(default_factory=lambda: np.zeros(2))
    zmp_ref: np.ndarray = field(default_factory=lambda: np.zeros(2))
    zmp_ref_margin_m: float = 0.0
    cmp: np.ndarray = field(default_factory=lambda: np.zeros(2))
    cmp_margin_m: float = 0.0
    cmp_clamped: np.ndarray = field(default_factory=lambda: np.zeros(2))
    com_acceleration: np.ndarray = field(default_factory=lambda: np.zeros(3))
    footsteps: tuple[Footstep, ...] = ()
    event: GaitEvent | None = None
    adaptation: StepAdaptation | None = None


class WalkingController:
    """A biped walking on the whole-body QP after a velocity command (see the module docstring).

    Example::

        walker = WalkingController(robot, (left_sole, right_sole), base_body, torso_body, q_start)
        walker.set_command((0.3, 0.0, 0.0))     # any cycle: vx [m/s], vy [m/s], yaw rate [rad/s]
        command = walker.compute(state)          # RobotState in, torque Command out
        walker.status.dcm, walker.steps

    Args:
        robot: The robot (torque actuators; its model gives the step limits).
        feet: The (left, right) foot frames.
        base_frame: The floating base's frame (held upright, heading between the feet).
        torso_frame: An upper-body frame held upright too, or None.
        reference_q: The standing configuration (nq,) the walk starts from (the posture target, the
            nominal stance width).
        config: Walking options.
        pin_model: The controller's analytic model (default ``robot.pin_model``).
        contact_force: ``foot -> measured normal force [N]`` (or None), for touchdown detection.
        contact_listener: Told ``{foot: in contact}`` whenever a foot's contact starts or ends (e.g.
            a base-state estimator's ``set_contacts``, so it switches its stance foot with the gait).
        arm_swing: Arm joint -> the leg joint it swings against (e.g. each shoulder pitch against the
            other side's hip pitch); its posture target is its start angle plus ``arm_swing_gain``
            times the leg joint's angle from its start.
        torso_counter_yaw: Joints (a, b) whose difference q_a - q_b [rad] turns the torso's yaw target
            by ``torso_yaw_gain`` times it (e.g. the left and right hip pitch); None: no turn.

    Raises:
        WBCSetupError: Bad options or frames.
        InvalidPlanningInput: A CoM height the legs cannot walk at.
    """

    reference_type = None

    def __init__(self, robot: Robot, feet: Sequence[str], base_frame: str, torso_frame: str | None,
                 reference_q: np.ndarray, config: WalkingConfig | None = None,
                 pin_model: pin.Model | None = None, contact_force: ContactForce | None = None,
                 contact_listener: Callable[[dict[str, bool]], object] | None = None,
                 arm_swing: Mapping[str, str] | None = None,
                 torso_counter_yaw: tuple[str, str] | None = None):
        self.config = cfg = config or WalkingConfig()
        if len(feet) != 2:
            raise WBCSetupError(f"walking needs two feet (left, right); got {list(feet)}")
        self.feet = (feet[0], feet[1])
        wbc_config = WBCConfig(**{**cfg.wbc.__dict__, "ramp_s": cfg.ramp_s, "torsion_m": cfg.torsion_m})
        contacts = [replace(c, mu=c.mu * cfg.friction_fraction)
                    for c in (foot_contact_from_model(robot, f) for f in self.feet)]
        self.standing: Standing = standing_controller(robot, self.feet, base_frame, torso_frame, pin_model,
                                                      wbc_config, contacts)
        self.wbc = self.standing.controller
        self.standing.com.set_cost(cfg.com_cost)
        self.standing.com.servo = cfg.height_gains
        self.standing.momentum.set_cost(cfg.momentum_cost)
        if self.standing.torso is not None:
            self.standing.torso.set_cost(cfg.torso_cost)
        self.model = self.wbc.model
        self._data = self.model.createData()
        self.reference_q = np.array(reference_q, dtype=float)
        points = self.wbc.contacts[self.feet[0]].contact.points_F
        self.sole_centre_F = points.mean(axis=0)
        self.limits = step_limits_from_model(robot, self.feet, points, self.reference_q, cfg.com_height_m)
        self.planner = FootstepPlanner(self.limits, cfg.timing, self.feet)
        self.omega = dcm_omega(cfg.com_height_m, float(np.linalg.norm(self.model.gravity.linear)))
        tube = dcm_tube(points, cfg.cmp_margin_m, cfg.dcm_gain_1_s, self.omega, cfg.dcm_tube_fraction)
        self.adapter = StepAdapter(self.planner, self.omega, tube, sole_centre_xy=(
            float(self.sole_centre_F[0]), float(self.sole_centre_F[1])), timing_weight=cfg.timing_weight,
            timing_threshold_m=cfg.timing_threshold_m,
            pushed_outward_m=cfg.pushed_outward_fraction * self.limits.max_outward_m,
            cross_clearance_m=cfg.cross_over_clearance_m, cross_gain_m=cfg.cross_over_gain_m,
            pushed_timing_along=cfg.pushed_timing_along, cross_quick=cfg.cross_over_quick)
        self.plans = WalkPlans(self.planner, cfg, self.omega)
        self.speed_loop = SpeedLoop(cfg)
        self.swing_tasks = {f: SwingFootTask(f, self.model, cfg.swing_cost, cfg.swing_gains,
                                             cfg.swing_orientation_cost) for f in self.feet}
        self.contact_force = contact_force
        self.contact_listener = contact_listener
        named = [j for pair in (arm_swing or {}).items() for j in pair] + list(torso_counter_yaw or ())
        m = self.model
        iq = {j: m.joints[m.getJointId(j)].idx_q for j in named if m.existJointName(j)}
        missing = sorted(set(named) - set(iq))
        if missing:
            raise WBCSetupError(f"arm_swing or torso_counter_yaw names joints the model does not have: "
                                f"{', '.join(missing)}")
        self._arm_swing = [(iq[arm], iq[leg]) for arm, leg in (arm_swing or {}).items()]
        yaw_pair = tuple(torso_counter_yaw or ())
        turns = len(yaw_pair) == 2 and cfg.torso_yaw_gain != 0.0 and self.standing.torso is not None
        self._counter_yaw = (iq[yaw_pair[0]], iq[yaw_pair[1]]) if turns else None  # None: the torso holds
        self._posture_target = self.reference_q.copy()
        self._reference_q_list = self.reference_q.tolist()
        self._in_contact: dict[str, bool] = {}
        self._fids = {f: self.model.getFrameId(f) for f in self.feet}
        self._sole_points = {f: self.wbc.contacts[f].contact.points_F.tolist() for f in self.feet}
        self._clamp = self.planner.clamp(VelocityCommand())
        self.status = WalkingStatus()
        #: The last cycle's time [s] in :meth:`compute`: planning and the whole-body QP layer.
        self.compute_time_s = 0.0
        self.gait: Gait | None = None
        self.reset()

    # ------------------------------------------------------------------ the command
    @property
    def command(self) -> CommandClamp:
        """The velocity command as requested and as applied (within the step limits)."""
        return self._clamp

    def set_command(self, command: VelocityCommand | tuple[float, float, float]) -> CommandClamp:
        """Walk at (vx [m/s], vy [m/s], yaw rate [rad/s]) in the body frame from now on (any cycle).

        The walk follows it from the next footstep planning (within ``replan_period_s``).

        Returns:
            What the step limits made of it.

        Raises:
            InvalidPlanningInput: A non-finite command.
        """
        self._clamp = self.planner.clamp(command)
        return self._clamp

    @property
    def velocity(self) -> VelocityCommand:
        """The command the walk follows now: the applied one, reached at ``max_acceleration``."""
        return self._command

    @property
    def steps(self) -> int:
        """Footsteps taken (touchdowns)."""
        return 0 if self.gait is None else self.gait.steps

    def reset(self) -> None:
        """Start again at the next state (standing on both feet where they are), at rest."""
        self.wbc.reset()
        for task in self.swing_tasks.values():
            self.wbc.remove_task(task)
        self.gait = None
        self._command, self._steer = VelocityCommand(), VelocityCommand()
        self._t_last: float | None = None
        #: The heading the walk holds [rad]: the start's, turned by the yaw-rate command.
        self.heading_ref_rad = 0.0
        self.speed_loop.reset()
        self._adaptation: StepAdaptation | None = None
        self._next_replan_s: float | None = None  # when the footsteps are planned next [s]
        self._in_contact = {}
        self.plans.reset()
        self._oriented: tuple[float, list[pin.SE3]] | None = None

    def _follow_command(self, t: float, gait: Gait) -> None:
        """The walk's command toward the applied one at ``max_acceleration``; the footsteps' command.

        The footsteps' command adds the heading error at ``heading_gain_1_s`` to the yaw rate and
        the speed loop's correction to the speed.
        """
        dt = 0.0 if self._t_last is None else max(0.0, t - self._t_last)
        self._t_last = t
        (ax, ay, aw), (gx, gy, gw) = self.config.max_acceleration, self._clamp.applied
        vx, vy, wz = self._command
        vx = vx + min(max(gx - vx, -ax * dt), ax * dt)
        vy = vy + min(max(gy - vy, -ay * dt), ay * dt)
        wz = wz + min(max(gw - wz, -aw * dt), aw * dt)
        self._command = VelocityCommand(vx, vy, wz)
        self.heading_ref_rad += wz * dt
        error = math.remainder(self.heading_ref_rad - gait.heading(t), 2.0 * math.pi)
        cx, cy = self.speed_loop.correction.tolist()
        self._steer = VelocityCommand(vx + cx, vy + cy, wz + self.config.heading_gain_1_s * error)

    def _correct_speed(self, t: float, gait: Gait) -> None:
        """After a touchdown: the speed loop (:mod:`~mbctl.control.wbc.speed_loop`) on the feet's midpoint."""
        mid = 0.5 * (gait.placed[self.feet[0]].position[:2] + gait.placed[self.feet[1]].position[:2])
        self.speed_loop.touchdown(t, mid, self._command[:2], self.heading_ref_rad, gait.steps)

    # ------------------------------------------------------------------ per cycle
    def _kinematics(self, state: RobotState) -> tuple[np.ndarray, np.ndarray, dict[str, pin.SE3]]:
        """CoM (3,) [m], its velocity (3,) [m/s] and the feet's poses X_WF, from the state."""
        m, d = self.model, self._data
        com = pin.centerOfMass(m, d, state.q, state.v).copy()
        vcom = d.vcom[0].copy()
        poses = {f: pin.updateFramePlacement(m, d, fid).copy() for f, fid in self._fids.items()}
        return com, vcom, poses

    def compute(self, state: RobotState, reference: object = None) -> Command:
        """Torques for ``state``: gait phase, footsteps, DCM, task targets, QP (see the module docstring).

        Args:
            state: Measured state, Pinocchio convention.
            reference: Unused (the command is set with :meth:`set_command`).

        Raises:
            WBCInfeasible: The QP has no solution and the QP's ``on_infeasible`` is "raise".
        """
        t0 = time.perf_counter()
        try:
            return self._compute(state)
        finally:
            self.compute_time_s = time.perf_counter() - t0

    def _compute(self, state: RobotState) -> Command:
        """:meth:`compute`'s work."""
        cfg = self.config
        t = state.time_s
        com, vcom, poses = self._kinematics(state)
        gait = self.gait or self._start(state, com, poses)
        replan = self._next_replan_s is None or t >= self._next_replan_s - 1e-9
        if replan:
            self._follow_command(t, gait)
        event = gait.advance(t, poses, self._steer, self._touching(gait, poses))
        if event is not None and event.kind == "touchdown":
            self._correct_speed(t, gait)
        self._tell_contacts()
        (cx, cy, _), (vx, vy, _) = com.tolist(), vcom.tolist()
        ix, iy = cx + vx / self.omega, cy + vy / self.omega  # the DCM
        xi = np.array([ix, iy])
        if replan or event is not None:
            last_error = self.status.dcm - self.status.dcm_ref  # a push moves the footstep later in the swing
            if gait.retargetable(t, math.hypot(*last_error.tolist()) > cfg.cmp_outside_after_m):
                gait.retarget(t, self._swing_footstep(gait, t, xi))
            self._next_replan_s = t + cfg.replan_period_s
        plan, steps = self.plans.plan(gait, t, self._steer)
        ref = plan.at(t)
        support = self._support_polygon(poses)
        (rx, ry), (zx, zy) = ref.xi.tolist(), ref.vrp.tolist()
        error_m = math.hypot(ix - rx, iy - ry)
        pushed = error_m > cfg.cmp_outside_after_m
        self.speed_loop.watch(error_m)
        k = cfg.dcm_gain_1_s if not pushed or gait.phase != DOUBLE else (
            cfg.hurried_double_gain_1_s if error_m > cfg.hurry_after_m else cfg.pushed_double_gain_1_s)
        gain = 1.0 + k / self.omega  # dcm_feedback's law, on floats
        cmp_xy = [zx + gain * (ix - rx), zy + gain * (iy - ry)]
        cmp = np.array(cmp_xy)
        if error_m > cfg.hurry_after_m:
            gait.hurry(t)
        pushed = pushed and cfg.cmp_outside_m > 0
        cmp_c = support.clamp(cmp_xy, -cfg.cmp_outside_m if pushed else cfg.cmp_margin_m)
        z_ref, vz_ref, az_ref = gait.height(t)
        px, py = cmp_c.tolist()  # the CoM's CMP
        last = self.wbc.last
        if cfg.moment_feedforward and self.wbc.steps and last is not None and not last.fallback:
            moment, fz = last.moment_about_W(com)  # CoP = CMP + (-m_y, m_x) / f_z
            if fz > 0.0:
                mx, my, _ = moment.tolist()
                px, py = px + my / fz, py + -mx / fz
        w2 = self.omega**2
        acc = np.array([w2 * (cx - px), w2 * (cy - py), az_ref])
        # the CoM task: its horizontal error is zero by construction, so the acceleration is the DCM law's
        self.standing.com.set_target([cx, cy, z_ref], [vx, vy, vz_ref], acc)
        self._orient(gait.heading(t), state.q)
        self._swing(gait, t)
        if self._arm_swing and cfg.arm_swing_gain:
            target, q0, q = self._posture_target, self._reference_q_list, state.q.tolist()
            for arm, leg in self._arm_swing:
                target[arm] = q0[arm] + cfg.arm_swing_gain * (q[leg] - q0[leg])
            self.standing.posture.set_target(target)
        self.status = WalkingStatus(t, gait.phase, gait.stance_name, xi, ref.xi, ref.vrp,
                                    support.margin((zx, zy)), cmp, support.margin(cmp_xy), cmp_c, acc,
                                    tuple(steps), event, self._adaptation)
        return self.wbc.compute(state)

    def _support_polygon(self, poses: dict[str, pin.SE3]) -> ConvexPolygon:
        """The support polygon: the hull of the active feet's contact points (x, y) [m] in W.

        Raises:
            InvalidPlanningInput: Non-finite foot poses.
        """
        points = []
        for f in self.feet:
            if self.wbc.contacts[f].active:  # R p + o for each point, on plain floats (a few per foot)
                (r0, r1, r2, ox), (s0, s1, s2, oy) = poses[f].homogeneous[:2].tolist()
                points += [[r0 * x + r1 * y + r2 * z + ox, s0 * x + s1 * y + s2 * z + oy]
                           for x, y, z in self._sole_points[f]]
        if not (points and math.isfinite(sum(x + y for x, y in points))):
            return ConvexPolygon.of_points(points)  # raises
        return ConvexPolygon.of_finite_points(points)

    def _tell_contacts(self) -> None:
        """Tell the contact listener which feet are on the ground (their contact in force), on a change."""
        in_contact = {f: self.wbc.contacts[f].active for f in self.feet}
        if in_contact != self._in_contact:
            self._in_contact = in_contact
            if self.contact_listener is not None:
                self.contact_listener(dict(in_contact))

    def _start(self, state: RobotState, com: np.ndarray, poses: dict[str, pin.SE3]) -> Gait:
        """Both feet held where they are, the tasks' targets at the state, the gait's start phase."""
        self.standing.hold(state)
        self.standing.posture.set_target(self.reference_q)
        self.gait = Gait(self.wbc, self.planner, self.config, self.sole_centre_F, poses, state.time_s, com)
        self.heading_ref_rad = self.gait.heading(state.time_s)
        return self.gait

    def _touching(self, gait: Gait, poses: dict[str, pin.SE3]) -> Callable[[str], bool]:
        """Whether a foot touches the ground: the measured force if any, else the sole's height."""
        def touching(foot: str) -> bool:
            if self.contact_force is not None:
                force = self.contact_force(foot)
                if force is not None:
                    return force > self.config.touchdown_force_n
            sole_z = poses[foot].act(self.sole_centre_F)[2]
            return bool(sole_z <= gait.ground_z + self.config.touchdown_height_m)
        return touching

    def _swing_footstep(self, gait: Gait, t: float, xi: np.ndarray) -> Footstep:
        """The swing footstep: the command's, moved by the step-adaptation QP if the DCM left its tube."""
        swing = gait.swing
        if swing is None:
            raise WBCSetupError("no swing foot to place outside single support")
        stance = gait.placed[swing.stance]
        nominal = self.planner.next_footstep(stance, self._steer)
        if not self.config.step_adaptation:
            return nominal
        plan, _ = self.plans.plan(gait, t, self._steer, nominal)
        ref = plan.at(t).xi
        t1 = float(plan.switch_times_s[0])
        # the swing's timing only where the QP needs it (a swing sample: not on the cycles in the tube)
        error = xi - ref
        pushed = math.hypot(*error.tolist()) > self.config.cmp_outside_after_m  # a push: wider outward limit
        adaptation = self.adapter.adapt(stance, nominal, error, t1 - t,
                                        lambda: self._step_timing(gait, t, t1, ref, pushed), pushed)
        self._adaptation = adaptation
        if adaptation.time_to_switch_s is not None:  # the switch moved: so does the touchdown
            end = t + adaptation.time_to_switch_s - (t1 - gait.phase_end)
            if abs(end - gait.phase_end) > RETIME_TOLERANCE_S:
                gait.retime(t, end)
        return adaptation.footstep

    def _step_timing(self, gait: Gait, t: float, t1: float, dcm_ref: np.ndarray,
                     pushed: bool = False) -> StepTiming | None:
        """The swing's timing for the adaptation QP (None: timing adaptation off, or no time left)."""
        cfg = self.config
        if not cfg.timing_adaptation:
            return None
        after = t1 - gait.phase_end  # the switch after the touchdown (within the double support)
        path = gait.swing.path if gait.swing is not None else None
        if path is None:
            return None
        # the foot's way to its footstep at no more than max_swing_speed_m_s, within the horizontal fraction
        x, y, _ = path.at(t).position.tolist()
        tx, ty, _ = path.target_position.tolist()
        speed = cfg.pushed_swing_speed_m_s if pushed else cfg.max_swing_speed_m_s
        reach_s = math.hypot(tx - x, ty - y) / speed
        earliest = max(gait.t_phase + cfg.min_single_support_s, t + cfg.min_swing_left_s,
                       gait.t_phase + (t - gait.t_phase + reach_s) / path.horizontal_fraction)
        nominal = gait.swing_nominal_end_s()
        if earliest >= nominal:
            return None
        return StepTiming(dcm_ref, nominal + after - t, earliest + after - t)

    def _orient(self, yaw: float, q: np.ndarray) -> None:
        """Pelvis and torso upright, heading ``yaw`` [rad] (the torso turned by ``torso_yaw_gain``)."""
        torso = self.standing.torso
        if self._counter_yaw is not None and torso is not None:  # its target follows the legs every cycle
            a, b = self._counter_yaw
            turn = self.config.torso_yaw_gain * (float(q[a]) - float(q[b]))
            torso.set_target(pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, yaw + turn), np.zeros(3)))
            torso = None  # (the pelvis's alone below, set only when the heading changed)
        tasks = [t for t in (self.standing.base, torso) if t is not None]
        last = self._oriented
        if last is not None and last[0] == yaw and all(
                task.transform_target_to_world is X for task, X in zip(tasks, last[1], strict=True)):
            return  # the targets this set last, unchanged since
        X = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, yaw), np.zeros(3))
        for task in tasks:
            task.set_target(X)
        self._oriented = (yaw, [task.transform_target_to_world for task in tasks])

    def _swing(self, gait: Gait, t: float) -> None:
        """The swing foot's task on its path; the other foot's task off."""
        for foot, task in self.swing_tasks.items():
            sample = gait.swing_sample(foot, t)
            if sample is None:
                self.wbc.remove_task(task)
                continue
            task.set_swing_target(sample)
            self.wbc.add_task(task)
