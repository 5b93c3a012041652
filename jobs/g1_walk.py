"""``mbctl g1-walk SCENARIO``: the G1 walks on the whole-body QP in torque mode, checked in the plant.

The Menagerie position actuators become torque motors (force ranges kept, never raised); the
walking controller (:class:`mbctl.control.wbc.WalkingController`: footsteps, a DCM plan with step
adaptation, swing feet and force-ramped contact switches on the whole-body QP) follows a velocity
command, (vx, vy, yaw rate) in the body frame, from the crouched start. In-process, touchdowns are
detected from the plant's contact sensor (the normal force MuJoCo applied on each foot's geoms);
over DDS from the sole's height (the base from the estimator).

The walking options are the gait's (``--gait``): ``quick`` by default (:func:`~mbctl.control.wbc.quick_gait`:
a step every 0.31 s, up to about 1 m/s), or ``normal`` (``WalkingConfig()``: a step every 0.6 s).

Scenarios (``--speed VX[,VY[,YAW_RATE]]`` m/s, m/s, rad/s; default in :data:`DEFAULT_SPEED`):

- ``forward``: (vx, vy, yaw rate) as given; ``backward``: the same with vx backward (-|vx|);
  ``side``: sideways; ``turn``: turning (the speed's vector as given in every case but backward).
- ``course``: waypoints (``--waypoints X,Y,YAW;...`` m, m, deg, or a file; default 12 over about
  10 m), the command toward each from the pelvis's pose, capped at ``--speed`` (the most forward,
  sideways and turning): :mod:`mbctl.jobs.g1_walk_course`; it passes when every waypoint was reached.
- ``push``: walking, pushed on the pelvis (``--impulse`` N s, default 15, over ``--push-hold`` s,
  default 0.1; ``--direction``
  deg, default eight directions 45 deg apart; ``--push-phase`` early, late or double, default early:
  :mod:`mbctl.jobs.g1_walk_push`); it passes when every push was survived. In-process only.

Checked in the plant (MuJoCo), by a :class:`~mbctl.sim.monitor.PlantMonitor`: the fall
(:data:`mbctl.robots.g1.G1_FALL`), the CoM, the feet's measured forces and slip. ``distance_m``
is the pelvis's horizontal displacement (the plant's own state in-process; over DDS the bridge's
truth log with ``--truth``, else the estimate: ``displacement_source``), ``commanded_displacement_m``
the command integrated over the run (speed x duration for a constant command; the heading turned
by the yaw rate), ``displacement_fraction`` the displacement along it over its length, ``yaw_rad``
the pelvis's turn (unwrapped along its path) and for a turn ``yaw_fraction`` that over the commanded
one; a course's command is its follower's, new each cycle, so the four command figures are null
there. A run passes (exit 0) when the G1 did not fall and the displacement (yaw for ``turn``) is
at least :data:`MIN_FRACTION` of the commanded one (``course``: every waypoint reached; ``push``:
every push survived); ``forward`` also needs a median foot slip within :data:`MAX_MEDIAN_SLIP_M`
(the issue's target for it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import pinocchio as pin

from mbctl.control.exceptions import WBCSetupError
from mbctl.control.loop import run
from mbctl.control.wbc import WalkingConfig, WalkingController, WBCConfig, quick_gait
from mbctl.jobs.g1_walk_choices import (
    WALK_DEFAULT_DURATION_S,
    WALK_DEFAULT_SPEED,
    WALK_GAITS,
    WALK_PUSH_PHASES,
    WALK_SCENARIOS,
)
from mbctl.jobs.g1_walk_course import CourseWalker, parse_waypoints
from mbctl.jobs.g1_walk_displacement import displacement_values, path_length
from mbctl.jobs.g1_walk_log import WalkLog
from mbctl.jobs.g1_walk_push import PUSH_HOLD_S, PhasePushes, pushes_duration_s
from mbctl.jobs.g1_wbc import check_scenario_and_duration
from mbctl.jobs.model_options import ModelOptions, build_models
from mbctl.jobs.plant import Plant, PlantOptions, dry_run, plant_lines, prepare_plant, report_plant
from mbctl.jobs.runner import Job, Outcome, RunContext, Work
from mbctl.jobs.truth import read_truth, truth_at_ticks
from mbctl.planners import VelocityCommand
from mbctl.robots.edits import scale_masses
from mbctl.robots.g1 import FEET, G1_FALL, KEYFRAME, PELVIS, TORSO, crouched_start, whole_body_g1
from mbctl.robots.model_pair import Robot
from mbctl.robots.registry import load_robot
from mbctl.sim.monitor import PlantMonitor

SCENARIOS = WALK_SCENARIOS
DEFAULT_SPEED = WALK_DEFAULT_SPEED
DEFAULT_DURATION_S = WALK_DEFAULT_DURATION_S
#: A run passes with at least this fraction of the commanded displacement (yaw for a turn) [-].
MIN_FRACTION = 0.9
#: ... and, walking forward, a median foot slip within this [m].
MAX_MEDIAN_SLIP_M = 0.005
#: Default push impulse [N s].
DEFAULT_IMPULSE_N_S = 15.0


def parse_speed(text: str) -> tuple[float, float, float]:
    """``"VX[,VY[,YAW_RATE]]"`` -> (vx [m/s], vy [m/s], yaw rate [rad/s]); missing ones are 0.

    Raises:
        WBCSetupError: Not 1 to 3 finite numbers.
    """
    parts = [p.strip() for p in text.split(",")]
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = []
    if not 1 <= len(values) <= 3 or not all(math.isfinite(v) for v in values):
        raise WBCSetupError(f"--speed must be VX[,VY[,YAW_RATE]] (m/s, m/s, rad/s), e.g. 0.3 or 0,0.2 or "
                            f"0,0,0.5; got {text!r}")
    return (values + [0.0, 0.0])[0], (values + [0.0, 0.0])[1], (values + [0.0, 0.0, 0.0])[2]


@dataclass(frozen=True)
class WalkParams:
    """Parameters of ``mbctl g1-walk`` (field names are the CLI options).

    Attributes:
        scenario: One of :data:`SCENARIOS`.
        speed: The command "VX[,VY[,YAW_RATE]]" (m/s, m/s, rad/s), or None for the scenario's.
        duration: Simulated time [s] (None: the scenario's default).
        impulse: Push impulse [N s] (push only; None: 15).
        direction: Push direction [deg] in the world's x-y plane (push only; None: eight, 45 deg apart).
        push_phase: The gait phase a push starts in: early, late or double (push only; None: early).
        push_hold: How long a push's force is held [s] (> 0; the force is impulse / hold; push only;
            None: :data:`~mbctl.jobs.g1_walk_push.PUSH_HOLD_S`, 0.1 s).
        waypoints: The course "X,Y,YAW;..." (m, m, deg) or a file of such lines (course only; None: the
            default course).
        gait: The walking options: "quick" (the default: :func:`~mbctl.control.wbc.quick_gait`, a step
            every 0.31 s, up to ~1 m/s) or "normal" (``WalkingConfig()``'s, a step every 0.6 s, capped
            near 0.6 m/s) (:data:`WALK_GAITS`).
        model_error: The controller model's link masses and inertias off by this [%].
        model_dir: Explicit G1 folder (else MENAGERIE_ROOT, the package cache).
        plant: In-process (with an optional link model) or the G1 over DDS.
        models: A hidden payload or mass error on the in-process plant, or the controller's model
            from a file.
    """

    scenario: str = "forward"
    speed: str | None = None
    duration: float | None = None
    impulse: float | None = None
    direction: float | None = None
    push_phase: str | None = None
    push_hold: float | None = None
    waypoints: str | None = None
    gait: str = "quick"
    model_error: float = 0.0
    model_dir: str | None = None
    plant: PlantOptions = PlantOptions()
    models: ModelOptions = ModelOptions()

    def __post_init__(self) -> None:
        self.plant.check_models(self.models)
        check_scenario_and_duration(self.scenario, SCENARIOS, self.duration)
        if self.speed is not None:
            parse_speed(self.speed)
        if not (math.isfinite(self.model_error) and -50 < self.model_error < 100):
            raise WBCSetupError(f"model_error must be a percentage in (-50, 100); got {self.model_error}")
        self._check_push()
        if self.waypoints is not None and self.scenario != "course":
            raise WBCSetupError("--waypoints applies to the course scenario only")
        if self.scenario == "course":
            parse_waypoints(self.waypoints)
        if self.gait not in WALK_GAITS:
            raise WBCSetupError(f"unknown gait {self.gait!r}; choose one of {', '.join(WALK_GAITS)}")

    def _check_push(self) -> None:
        names = ("impulse", "direction", "push_phase", "push_hold")
        given = [n for n in names if getattr(self, n) is not None]
        if self.scenario != "push":
            if given:
                raise WBCSetupError(f"--{given[0].replace('_', '-')} applies to the push scenario only")
            return
        if self.plant.interface == "dds":
            raise WBCSetupError("the push scenario needs the in-process plant (--interface sim): over DDS "
                                "nothing can push the robot")
        if self.impulse is not None and not (math.isfinite(self.impulse) and self.impulse >= 0):
            raise WBCSetupError(f"impulse must be a finite impulse >= 0 N s; got {self.impulse}")
        if self.direction is not None and not math.isfinite(self.direction):
            raise WBCSetupError(f"direction must be a finite angle in degrees; got {self.direction}")
        if self.push_hold is not None and not (math.isfinite(self.push_hold) and self.push_hold > 0):
            raise WBCSetupError(f"push_hold must be a finite time > 0 s; got {self.push_hold}")
        if self.push_phase is not None and self.push_phase not in WALK_PUSH_PHASES:
            raise WBCSetupError(f"unknown push phase {self.push_phase!r}; choose one of "
                                f"{', '.join(WALK_PUSH_PHASES)}")

    @property
    def duration_s(self) -> float:
        """The simulated time [s] (one push: its start, its period and the start phase)."""
        if self.duration is not None:
            return self.duration
        if self.scenario == "push" and self.direction is not None:
            return pushes_duration_s(1)
        return DEFAULT_DURATION_S[self.scenario]

    @property
    def push_directions_deg(self) -> list[float]:
        """The push directions [deg] (none outside the push scenario)."""
        if self.scenario != "push":
            return []
        return [k * 45.0 for k in range(8)] if self.direction is None else [self.direction]

    @property
    def command(self) -> VelocityCommand:
        """The velocity command (backward: vx made negative)."""
        vx, vy, wz = DEFAULT_SPEED[self.scenario] if self.speed is None else parse_speed(self.speed)
        return VelocityCommand(-abs(vx) if self.scenario == "backward" else vx, vy, wz)


def g1_walk_params(scenario: str = "forward", speed: str | None = None, duration: float | None = None,
                   impulse: float | None = None, direction: float | None = None,
                   push_phase: str | None = None, push_hold: float | None = None,
                   waypoints: str | None = None, gait: str = "quick", model_error: float = 0.0,
                   model_dir: str | None = None, **options: Any) -> WalkParams:
    """``mbctl g1-walk``: speed "VX[,VY[,YAW_RATE]]", duration, push, gait, model error.

    Units: duration [s], impulse [N s], direction [deg], push hold [s], model error [%].

    ``options`` are the G1 jobs' plant options (:func:`mbctl.jobs.options.plant`'s, in their units)
    and the model options (``payload``, ``plant_error``, ``controller_model``); the signature lists
    them (:data:`_PARAMETERS`), so the command line and ``mbctl sweep`` read the same names.
    """
    from mbctl.jobs.options import plant

    model = {k: options.pop(k) for k in _MODEL_OPTIONS if k in options}
    return WalkParams(scenario, speed, duration, impulse, direction, push_phase, push_hold, waypoints, gait,
                      model_error, model_dir, plant(**options), ModelOptions(**model))


#: The model options and their defaults (``mbctl.jobs.model_options.ModelOptions``'s fields).
_MODEL_OPTIONS = {"payload": (str | None, None), "plant_error": (float, 0.0),
                  "controller_model": (str | None, None)}


def _signature() -> None:
    """Give :func:`g1_walk_params` the full signature: its own options, the plant's, the model's."""
    import inspect
    import typing

    from mbctl.jobs.options import plant

    own = [p for p in inspect.signature(g1_walk_params).parameters.values() if p.kind != p.VAR_KEYWORD]
    hints = {**typing.get_type_hints(g1_walk_params), **typing.get_type_hints(plant)}
    keyword = inspect.Parameter.POSITIONAL_OR_KEYWORD
    plant_params = [p.replace(kind=keyword) for p in inspect.signature(plant).parameters.values()]
    model = [inspect.Parameter(k, keyword, default=d) for k, (_, d) in _MODEL_OPTIONS.items()]
    hints.update({k: t for k, (t, _) in _MODEL_OPTIONS.items()})
    g1_walk_params.__signature__ = inspect.Signature(  # type: ignore[attr-defined]
        [*own, *plant_params, *model], return_annotation=WalkParams)
    g1_walk_params.__annotations__ = {p: hints[p] for p in inspect.signature(g1_walk_params).parameters}
    g1_walk_params.__annotations__["return"] = WalkParams


_signature()


#: The G1's arm swing: each shoulder pitch against the other side's hip pitch.
G1_ARM_SWING = {"left_shoulder_pitch_joint": "right_hip_pitch_joint",
                "right_shoulder_pitch_joint": "left_hip_pitch_joint"}


#: The joints whose difference turns the G1's torso against the legs (``WalkingConfig.torso_yaw_gain``).
G1_TORSO_COUNTER_YAW = ("left_hip_pitch_joint", "right_hip_pitch_joint")


def g1_walker(robot: Robot, start_q: np.ndarray, pin_model: pin.Model | None = None,
              config: WalkingConfig | None = None, gait: str = "quick") -> WalkingController:
    """The walking controller on a torque-mode G1 (G1 frame names, arm swing) from the start configuration.

    ``config`` (else the ``gait``'s options: :data:`WALK_GAITS`) with the QP damping where infeasible.
    """
    if config is None:
        wbc = WBCConfig(on_infeasible="damp")
        config = quick_gait(wbc=wbc) if gait == "quick" else WalkingConfig(wbc=wbc)
    return WalkingController(robot, FEET, PELVIS, TORSO, start_q, config, pin_model, arm_swing=G1_ARM_SWING,
                             torso_counter_yaw=G1_TORSO_COUNTER_YAW)


def prepare(params: WalkParams, robot: Robot | None = None) -> Work:
    """Load the G1 (or take ``robot``, a Menagerie G1) as the whole-body jobs run it (no output yet).

    Torque mode, palm sites, foot contact sensors: :func:`~mbctl.robots.g1.whole_body_g1`.
    """
    g1 = robot or load_robot("g1", model_dir=params.model_dir)
    models = build_models(whole_body_g1(g1), params.models, whole_body_g1)
    robot = models.plant
    pin_model = models.controller_model
    if params.model_error:
        pin_model = scale_masses(pin_model, 1.0 + params.model_error / 100.0)
    start_q = crouched_start(robot)
    walker = g1_walker(robot, start_q, pin_model, gait=params.gait)  # bad limits or frames: exit 2 first
    walker.set_command(params.command)
    plant = prepare_plant(params.plant, robot, KEYFRAME, start_q=start_q, contact_forces=True)

    def work(ctx: RunContext) -> Outcome:
        with plant(ctx) as p:
            ctx.sections["models"] = models.section()
            if p.options.dry_run:
                return dry_run(ctx, p, params.duration_s)
            return _run(ctx, params, robot, walker, p)

    return work


def _run(ctx: RunContext, params: WalkParams, robot: Robot, walker: WalkingController, p: Plant) -> Outcome:
    iface, sim = p.interface, p.sim
    monitor, pushes = None, None
    if sim is not None:  # the plant's own measurements: in-process only
        feet = {name: cs.contact.geoms for name, cs in walker.wbc.contacts.items()}
        monitor = PlantMonitor(sim, feet, sites=FEET, fall_rule=G1_FALL.reason).attach()
        walker.contact_force = lambda f: monitor.contacts[f].normal_n if monitor.contacts else None
        if params.scenario == "push":
            pushes = PhasePushes(sim.model, walker, params.push_directions_deg,
                                 DEFAULT_IMPULSE_N_S if params.impulse is None else params.impulse,
                                 params.push_phase or "early",
                                 PUSH_HOLD_S if params.push_hold is None else params.push_hold)
            sim.add_perturbation(pushes)
    estimator = getattr(iface, "estimator", None)  # the base from an estimator (over DDS, --estimate)
    if estimator is not None and hasattr(estimator, "set_contacts"):
        walker.contact_listener = estimator.set_contacts  # it switches its stance foot with the gait
    n = max(1, int(round(params.duration_s / iface.control_period_s)))
    mass_kg = monitor.mass_kg if monitor is not None else float(robot.mj_model.body_subtreemass[1])
    mg_n = mass_kg * float(np.linalg.norm(robot.mj_model.opt.gravity))
    log = WalkLog(ctx, walker, monitor, pushes, n, mg_n)
    clamp = walker.command
    ctx.sections["inputs"] = {
        "scenario": params.scenario, "gait": params.gait, "keyframe": KEYFRAME,
        "controller": "walking on the whole-body QP (control/wbc)",
        "command_requested": list(clamp.requested), "command_applied": list(clamp.applied),
        "command_limited_by": list(clamp.limited_by), "model_error_pct": params.model_error,
        "step_limits": walker.limits.__dict__, "timing_s": walker.config.timing.__dict__,
        "com_height_m": walker.config.com_height_m, "tasks": [t.name for t in walker.wbc.tasks]}
    ctx.progress.start(n, f"g1-walk {params.scenario}")
    start = sim.read_state() if sim is not None else iface.read_state()
    course = None
    if params.scenario == "course":
        course = CourseWalker(walker, parse_waypoints(params.waypoints), params.command)
    run_log = run(iface, course or walker, None, params.duration_s, on_step=log.on_step)
    values = log.values()
    if pushes is not None:
        values.update(pushes.values(bool(values["fell"])))
    end = sim.read_state() if sim is not None else iface.read_state()
    q0, q1, source = start.q, end.q, "plant" if sim is not None else "estimator"
    if p.options.truth is not None and run_log.cycles:  # over DDS, the bridge's own record of the pelvis
        q0, q1 = (_truth_q(row) for row in truth_at_ticks(read_truth(p.options.truth),
                                                           run_log.tick[[0, run_log.cycles - 1]]))
        source = "truth log"
    command = None if course is not None else clamp.applied  # a course's command is the follower's
    values.update(displacement_values(q0, q1, run_log.t_s, command, run_log.q), displacement_source=source)
    if course is not None:
        cycle_s = 2 * walker.config.timing.step_s
        values.update(course.values(q1), path_m=path_length(run_log.row_time_s, run_log.q, cycle_s))
    truth_fell = report_plant(ctx, p, run_log, G1_FALL.base_min_z_m)
    if truth_fell is not None:  # the bridge's truth log has the last word on a DDS run
        values.update(log.state_fall.truth_values(truth_fell))
    values["foot_slip_source"] = "plant" if sim is not None else None
    if sim is None and "truth_max_foot_slip_m" in values:  # over DDS: each stance's slip from the truth log
        values.update(max_foot_slip_m=values["truth_max_foot_slip_m"],
                      median_foot_slip_m=values["truth_median_foot_slip_m"], foot_slip_source="truth log")
    drift = values.get("estimator_position_error_max_m")
    if drift is not None and values["distance_m"] > 0.1:  # the estimator's worst error per metre walked
        values["estimator_drift_m_per_m"] = drift / values["distance_m"]
    from mbctl.jobs.g1_walk_plots import walk_plots

    walk_plots(ctx, log, walker, params, values)
    outcome = _outcome(params, values, iface.time_s)
    if clamp.clamped:  # what the step limits made of the command, and where more is to be had
        more = "; the quick gait (the default) steps quicker, up to ~1 m/s" if params.gait == "normal" else ""
        outcome = replace(outcome, summary=(*outcome.summary, (
            f"command {_triple(clamp.requested)} limited to {_triple(clamp.applied)} by the "
            f"{', '.join(clamp.limited_by)} limit{more}")))
    return outcome


def _unapplied(v: dict[str, Any], time_s: float) -> str:
    """What a run too short for its pushes left out, and the duration that takes them all."""
    left, n = v["pushes_planned"] - v["pushes_applied"], v["pushes_planned"]
    return (f"; {left} not applied: the run ended at {time_s:.2f} s before they were due ({n} pushes need "
            f"--duration {pushes_duration_s(n):g} or more)") if left else ""


def _triple(command: VelocityCommand) -> str:
    return ",".join(f"{x:.3g}" for x in command)


def _truth_q(row: np.void) -> np.ndarray:
    """The base's configuration (7,) [m, quaternion xyzw] from a truth-log row (the bridge's plant)."""
    return np.array([row["base_x_m"], row["base_y_m"], row["base_z_m"], row["base_qx"], row["base_qy"],
                     row["base_qz"], row["base_qw"]], dtype=float)


def _outcome(params: WalkParams, v: dict[str, Any], time_s: float) -> Outcome:
    """Pass: no fall, the median slip within bound, the commanded displacement or turn (push: survived)."""
    fraction = v["yaw_fraction"] if params.scenario == "turn" else v["displacement_fraction"]
    slip = v["median_foot_slip_m"]
    checks = [v["fell"] is False]
    forward = params.scenario == "forward"
    slip_bound = f", median foot slip <= {MAX_MEDIAN_SLIP_M * 1e3:g} mm" if forward else ""
    if slip_bound:
        checks.append(slip is None or slip <= MAX_MEDIAN_SLIP_M)
    if params.scenario == "push":
        checks.append(v["pushes_survived"] == v["pushes_planned"])
    elif params.scenario == "course":
        checks.append(v["waypoints_reached"] == v["waypoints_planned"])
    else:
        checks.append(fraction is not None and fraction >= MIN_FRACTION)
    at = f" at {v['fall_time_s']:.2f} s" if v["fall_time_s"] is not None else ""
    fell = f"FELL ({v['fall_reason']}){at}" if v["fell"] else "walked"
    what = "turn" if params.scenario == "turn" else "displacement"
    force = (v.get("contact_force_error") or {}).get("single") or {}
    # a course's command changes with each waypoint: its integral is no measure (the waypoints are)
    of_command = "" if params.scenario == "course" else (
        f", {what} {100 * (fraction or 0):.1f} % of the command ({v['yaw_rad']:.2f} of "
        f"{v['commanded_yaw_rad']:.2f} rad turned)")
    moved = (f"{v['path_m']:.2f} m walked ({v['distance_m']:.3f} m from the start)" if "path_m" in v
             else f"{v['distance_m']:.3f} m at {v['mean_speed_m_s'] or 0:.3f} m/s")
    lines = (
        f"g1-walk {params.scenario} {time_s:.2f} s: {fell}; {v['steps']} steps, {moved}{of_command}",
        f"foot slip max {_mm(v['max_foot_slip_m'])}, median {_mm(v['median_foot_slip_m'])}"
        f"{' (truth log)' if v.get('foot_slip_source') == 'truth log' else ''}; DCM RMS "
        f"{_mm(v['dcm_rms_m'])}; ZMP reference margin min {_mm(v['min_zmp_margin_m'])}; contact force QP vs "
        f"MuJoCo in single support median {_n(force.get('median_N'))}, p95 {_n(force.get('p95_N'))}, max "
        f"{_n(force.get('max_N'))}",
        f"controller {v['controller_time_median_us']:.0f} us median (planning and whole-body QP; the QP "
        f"{v['qp_solve_time_median_us'] or 0:.0f} us); steps adapted "
        f"{v['step_adaptations']['steps_adapted']} ({v['step_adaptations']['steps_limited']} held short by a "
        f"limit); QP solved without its joint-limit bounds in {v['qp_relaxed_cycles']} cycles; touchdowns "
        f"{v['touchdowns']}", *plant_lines(v))
    if params.scenario == "push":
        lines += (f"pushes: {v['pushes_survived']} of {v['pushes_planned']} survived ("
                  + "".join(f"{p['impulse_n_s']:g} N s over {p['hold_s']:g} s, {p['force_n']:g} N; "
                            for p in v["pushes"][:1])
                  + "; ".join(f"{p['direction_deg']:g} deg at {p['time_s']:.2f} s, {p['phase']}: "
                              f"{'survived' if p['survived'] else 'FELL'}, recovered in "
                              f"{p['recovery_steps'] if p['recovery_steps'] is not None else 'n/a'} steps"
                              for p in v["pushes"]) + ")" + _unapplied(v, time_s),)
        bound = "no fall, every push survived"
    elif params.scenario == "course":
        reached = [w["reached_at_s"] for w in v["waypoints"] if w["reached_at_s"] is not None]
        when = (f"the course done at {v['course_time_s']:.1f} s" if v["course_time_s"] is not None
                else f"the last at {reached[-1]:.1f} s" if reached else "none")
        lines += (f"course: {v['waypoints_reached']} of {v['waypoints_planned']} waypoints reached (within "
                  f"0.10 m and 10 deg), {when}; final error "
                  f"{v['final_position_error_m']:.3f} m, {v['final_yaw_error_deg']:.1f} deg",)
        bound = "no fall, every waypoint reached"
    else:
        bound = f"no fall, {what} >= {MIN_FRACTION:.0%} of the commanded{slip_bound}"
    return Outcome(all(checks), lines, bound)


def _mm(x: float | None) -> str:
    return "n/a" if x is None else f"{x * 1e3:.2f} mm"


def _n(x: float | None) -> str:
    return "n/a" if x is None else f"{x:.1f} N"


G1_WALK = Job("g1-walk", prepare)
