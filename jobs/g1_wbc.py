"""``mbctl g1-wbc SCENARIO``: whole-body inverse dynamics on the floating-base G1, in torque mode.

The Menagerie position actuators become torque motors (force ranges kept); the standing
whole-body controller (:func:`mbctl.control.wbc.standing_controller`: CoM, pelvis and torso
orientation, posture, angular-momentum damping, and per scenario a swing foot or the palms,
:mod:`mbctl.jobs.wbc_scenarios`) computes the torques each control cycle from the Pinocchio
model; MuJoCo executes them. The run goes through the control loop (:func:`mbctl.control.loop.run`)
on the simulator like every other job.

Checked in the plant (MuJoCo), not in the model, by a :class:`~mbctl.sim.monitor.PlantMonitor`:
the CoM (the robot's subtree CoM), the feet (site positions), the contact forces MuJoCo applied
on the foot geoms, and whether the G1 fell (:data:`mbctl.robots.g1.G1_FALL`). Foot slip is the
horizontal drift of a supporting foot (full contact weight, at least 10 % of m g measured on it)
from where it last started to support.

If the QP has no solution (a push it cannot hold), the controller switches to joint damping
and the plant runs on until the robot falls or the time is up: the report says both what the
controller did (``controller_fallback_at_s``) and whether the robot fell. Each scenario has its
bounds (:data:`BOUNDS`); a run outside them exits 1.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from mbctl.control.exceptions import WBCSetupError
from mbctl.control.loop import run
from mbctl.control.wbc import Scheduled, Standing, WBCConfig, standing_controller
from mbctl.jobs.choices import WBC_DEFAULT_DURATION_S, WBC_SCENARIOS
from mbctl.jobs.model_options import ModelOptions, build_models
from mbctl.jobs.plant import Plant, PlantOptions, dry_run, plant_lines, prepare_plant, report_plant
from mbctl.jobs.recording import q_columns
from mbctl.jobs.runner import Job, Outcome, RunContext, Work
from mbctl.jobs.truth import truth_com
from mbctl.jobs.wbc_log import BATCH, BATCH_IN_PROCESS, WBCLog
from mbctl.jobs.wbc_scenarios import PUSH_PERIOD_S, scenario
from mbctl.robots.edits import scale_masses
from mbctl.robots.g1 import FEET, G1_FALL, KEYFRAME, PELVIS, TORSO, crouched_start, whole_body_g1
from mbctl.robots.model_pair import Robot
from mbctl.robots.registry import load_robot
from mbctl.sim.monitor import PlantMonitor

#: The scenarios and their default simulated time [s] (the CLI's help lists them from jobs/choices).
SCENARIOS = WBC_SCENARIOS
DEFAULT_DURATION_S = WBC_DEFAULT_DURATION_S
#: Default push impulse [N s].
DEFAULT_IMPULSE_N_S = 10.0


def check_scenario_and_duration(scenario: str, scenarios: tuple[str, ...], duration_s: float | None,
                                plant: PlantOptions | None = None) -> None:
    """A G1 whole-body job's scenario and duration [s] (None: the scenario's own), as bad input.

    Args:
        scenario: The scenario asked for.
        scenarios: The job's scenarios.
        duration_s: The duration asked for [s], or None.
        plant: The plant options, checked against the duration (a latency as long as the run); None:
            the duration checked against :data:`mbctl.jobs.plant.MAX_RUN_S` alone.

    Raises:
        WBCSetupError: An unknown scenario, or a duration that is not a positive number.
        SizeLimitError: A duration over the run-length limit.
        PlantOptionError: A link latency at least the duration.
    """
    if scenario not in scenarios:
        raise WBCSetupError(f"unknown scenario {scenario!r}; choose one of {', '.join(scenarios)}")
    if duration_s is not None and not (math.isfinite(duration_s) and duration_s > 0):
        raise WBCSetupError(f"duration must be a positive number of seconds; got {duration_s}")
    (plant or PlantOptions()).check_duration(duration_s)


@dataclass(frozen=True)
class Bounds:
    """What a scenario must achieve in the plant (besides not falling).

    Attributes:
        com_rms_m: Largest CoM tracking error, RMS over the run [m].
        foot_slip_m: Largest horizontal slip of a supporting foot [m].
    """

    com_rms_m: float
    foot_slip_m: float

    def describe(self) -> str:
        """The bounds in words, for the report."""
        return f"CoM RMS < {self.com_rms_m * 1e3:g} mm, foot slip < {self.foot_slip_m * 1e3:g} mm"


#: Per scenario. Measured with the exact model (``mbctl g1-wbc SCENARIO``): CoM RMS stand 0.4 mm,
#: squat 2.1, one-foot 1.4, reach 5.1, push 6.8 mm; the bounds leave room for model error of a few
#: percent and catch a robot that "stands" far off its reference.
BOUNDS = {
    "stand": Bounds(5e-3, 1e-3),
    "squat": Bounds(5e-3, 1e-3),
    "one-foot": Bounds(1e-2, 2e-3),
    "reach": Bounds(1e-2, 1e-3),
    "push": Bounds(2e-2, 1e-2),
}


@dataclass(frozen=True)
class WBCParams:
    """Parameters of ``mbctl g1-wbc`` (field names are the CLI options).

    Attributes:
        scenario: One of :data:`SCENARIOS`.
        duration: Simulated time [s] (None: the scenario's default).
        impulse: Push impulse [N s] (push scenario only; None: 10 N s).
        direction: Push direction [deg] in the world x-y plane (0 = +x, the robot's front; 90 =
            +y, its left); None: eight directions 45 deg apart, 2 s apart (push scenario only).
        model_error: The controller model's link masses and inertias off by this [%].
        model_dir: Explicit G1 folder (else MENAGERIE_ROOT, the package cache).
        plant: In-process (with an optional link model: latency, jitter, drops, IMU noise, the
            estimator) or the G1 over DDS (no pushes there: the bridge has no push input).
        models: A hidden payload or mass error on the in-process plant, or the controller's model
            from a file (e.g. an ``identified.xml``); ``model_error`` then scales that model.
    """

    scenario: str = "stand"
    duration: float | None = None
    impulse: float | None = None
    direction: float | None = None
    model_error: float = 0.0
    model_dir: str | None = None
    plant: PlantOptions = PlantOptions()
    models: ModelOptions = ModelOptions()

    def __post_init__(self) -> None:
        self.plant.check_models(self.models)
        check_scenario_and_duration(self.scenario, SCENARIOS, self.duration)
        if self.scenario != "push" and (self.impulse is not None or self.direction is not None):
            given = "--impulse" if self.impulse is not None else "--direction"
            raise WBCSetupError(f"{given} applies to the push scenario only; scenario {self.scenario!r} "
                                "has no pushes")
        if self.impulse is not None and not (np.isfinite(self.impulse) and self.impulse >= 0):
            raise WBCSetupError(f"impulse must be a finite impulse >= 0 N s; got {self.impulse}")
        if self.direction is not None and not np.isfinite(self.direction):
            raise WBCSetupError(f"direction must be a finite angle in degrees; got {self.direction}")
        if not (np.isfinite(self.model_error) and -50 < self.model_error < 100):
            raise WBCSetupError(f"model_error must be a percentage in (-50, 100); got {self.model_error}")
        if self.plant.interface == "dds" and self.scenario == "push":
            raise WBCSetupError("the push scenario needs the in-process plant (--interface sim): over DDS "
                                "nothing can push the robot")
        self.plant.check_duration(self.duration_s)  # the scenario's own when none is given

    @property
    def duration_s(self) -> float:
        """The simulated time [s]."""
        if self.duration is not None:
            return self.duration
        if self.scenario == "push" and self.direction is not None:
            return 1.0 + PUSH_PERIOD_S
        return DEFAULT_DURATION_S[self.scenario]

    @property
    def impulse_n_s(self) -> float:
        """The push impulse [N s]."""
        return DEFAULT_IMPULSE_N_S if self.impulse is None else self.impulse


def g1_whole_body(robot: Robot, pin_model: pin.Model | None = None,
                  config: WBCConfig | None = None) -> Standing:
    """The standing whole-body controller on a torque-mode G1 with palm sites (G1 frame names)."""
    return standing_controller(robot, FEET, PELVIS, TORSO, pin_model, config)


def prepare(params: WBCParams, robot: Robot | None = None) -> Work:
    """Load the G1 (or take ``robot``, a Menagerie G1) as the whole-body jobs run it (no output yet).

    Torque mode, palm sites, foot contact sensors: :func:`~mbctl.robots.g1.whole_body_g1`.
    """
    g1 = robot or load_robot("g1", model_dir=params.model_dir)
    models = build_models(whole_body_g1(g1), params.models, whole_body_g1)
    robot = models.plant
    factor = 1.0 + params.model_error / 100.0
    pin_model = models.controller_model
    if params.model_error:
        pin_model = scale_masses(pin_model, factor)
    # over DDS this connects now: no robot, or one outside its limits, is bad input (exit 2)
    plant = prepare_plant(params.plant, robot, KEYFRAME, start_q=crouched_start(robot), contact_forces=True)

    def work(ctx: RunContext) -> Outcome:
        with plant(ctx) as p:
            ctx.sections["models"] = models.section()
            if p.options.dry_run:
                return dry_run(ctx, p, params.duration_s)
            return _run(ctx, params, robot, pin_model, p)

    return work


def _run(ctx: RunContext, params: WBCParams, robot: Robot, pin_model: pin.Model | None, p: Plant) -> Outcome:
    iface, sim = p.interface, p.sim  # sim: the in-process plant (None over DDS)
    wb = g1_whole_body(robot, pin_model, WBCConfig(on_infeasible="damp"))
    wb.hold(iface.read_state())
    schedule, pushes = scenario(params.scenario, wb, robot.mj_model, params.impulse_n_s, params.direction)
    monitor = None
    if sim is not None:  # the plant's own measurements: in-process only
        if pushes is not None:
            sim.add_perturbation(pushes)
        feet = {name: cs.contact.geoms for name, cs in wb.controller.contacts.items()}
        monitor = PlantMonitor(sim, feet, sites=FEET, fall_rule=G1_FALL.reason).attach()
    n = max(1, int(round(params.duration_s / iface.control_period_s)))
    # the plant's weight m g [N]: the robot's true mass, whatever the controller's model says
    mass_kg = monitor.mass_kg if monitor is not None else float(robot.mj_model.body_subtreemass[1])
    batch = BATCH_IN_PROCESS if sim is not None else BATCH  # over DDS, each stall within a period
    log = WBCLog(ctx, wb, monitor, pushes, n, mass_kg * float(np.linalg.norm(robot.mj_model.opt.gravity)),
                 q_columns(robot), batch)
    ctx.sections["inputs"] = {"scenario": params.scenario, "keyframe": KEYFRAME,
                              "controller": "whole-body inverse dynamics QP (control/wbc)",
                              "model_error_pct": params.model_error,
                              "tasks": [t.name for t in wb.controller.tasks]}
    ctx.progress.start(n, f"g1-wbc {params.scenario}")
    # the loop's rows (the estimated base pose) serve the truth checks only: the log records the rest
    run_log = run(iface, Scheduled(wb.controller, schedule), None, params.duration_s, on_step=log.on_step,
                  log_batch=batch, rows=p.options.truth is not None)
    values = log.values(sim)
    truth_fell = report_plant(ctx, p, run_log, G1_FALL.base_min_z_m)
    if p.options.truth is not None:
        com_W = truth_com(p.options.truth, run_log.tick, run_log.q[:1])  # every tick; the first estimate
        values = log.with_truth(com_W, bool(truth_fell))
    from mbctl.jobs.wbc_plots import wbc_plots

    wbc_plots(ctx, log, params, values)
    bounds = BOUNDS[params.scenario]
    fell = values["fell"]
    if "truth_max_foot_slip_m" in values:  # over DDS with the bridge's truth log
        values["max_foot_slip_m"] = values["truth_max_foot_slip_m"]
    slip = values["max_foot_slip_m"]  # None over DDS without the truth log: not observed
    ok = (not fell and values["com_error_rms_m"] < bounds.com_rms_m
          and (slip is None or slip < bounds.foot_slip_m))
    controller = ("QP throughout" if values["controller_fallback_at_s"] is None else
                  f"QP infeasible at t={values['controller_fallback_at_s']:.3f} s, then joint damping")
    summary = (
        f"g1-wbc {params.scenario} {iface.time_s:.2f} s: "
        f"{'FELL (' + str(values['fall_reason']) + ')' if fell else 'stood'}; controller: {controller}; "
        f"CoM RMS {values['com_error_rms_m'] * 1e3:.2f} mm, max foot slip "
        f"{'n/a' if slip is None else f'{slip * 1e3:.3f} mm'}, contact force error "
        f"{values['contact_force_rel_error'] * 100:.2f} % of m g median "
        f"(95th percentile {values['contact_force_rel_error_p95'] * 100:.2f} %, max "
        f"{values['contact_force_rel_error_max'] * 100:.2f} %), controller "
        f"{values['controller_time_median_us']:.0f} us (QP {values['qp_solve_time_median_us']:.0f} us) "
        f"median, saturated steps {values.get('torque_saturation_steps', 'n/a')}", *_overhead_line(values),
        *plant_lines(values))
    return Outcome(ok, summary, f"{bounds.describe()}; did not fall")


def _overhead_line(values: dict) -> list[str]:
    """The cycle's time beyond its controller and its physics step, in-process (no line over DDS)."""
    us = values.get("cycle_overhead_median_us", float("nan"))
    if not math.isfinite(us):
        return []
    return [f"cycle {values['cycle_time_median_us']:.0f} us median: controller, physics step "
            f"{values['physics_step_time_median_us']:.0f} us, and {us:.0f} us beyond them (mean "
            f"{values['cycle_overhead_mean_us']:.0f} us: targets, state, command, plant monitor, CSV row)"]


G1_WBC = Job("g1-wbc", prepare)
