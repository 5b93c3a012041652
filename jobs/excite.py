"""``mbctl excite ROBOT``: drive the plant through an exciting motion and record what identification needs.

Fixed-base robots (torque motors; position actuators are turned into motors): a Fourier-series
trajectory of every actuated joint, optimised for the condition number of the regressor within
the joint, speed and torque limits (:func:`mbctl.planners.excitation.design_excitation`, on the
robot's own model: the nominal one, which is all a real excitation design knows, and the same
trajectory whatever ``--controller-model`` the tracking uses, so tracking errors compare like for
like), tracked by joint-space computed torque. The Menagerie G1: a whole-body excitation on its feet
(:mod:`mbctl.jobs.excite_g1`).

The plant may hide a truth (``--payload``, ``--plant-error``); the controller and the design never
see it. Every cycle streams a row of the identification log (:mod:`mbctl.jobs.ident_log`). The G1
also runs over its low-level DDS (``--interface dds`` and the other plant options of the G1 jobs,
:mod:`mbctl.jobs.plant`); fixed-base robots run in-process only.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from mbctl.control.computed_torque import ComputedTorque
from mbctl.control.exceptions import ControllerSetupError
from mbctl.control.gains import gains_from_frequency
from mbctl.control.loop import run
from mbctl.jobs.ident_log import CONTACTS, CSV_NAME, SECTION, TORQUES, header, log_row
from mbctl.jobs.model_options import ModelOptions, Models, build_models, models_line
from mbctl.jobs.plant import PlantOptions
from mbctl.jobs.plots import joint_colors, new_figure
from mbctl.jobs.recording import q_columns, v_columns
from mbctl.jobs.runner import Job, Outcome, RunContext, Work
from mbctl.planners.excitation import (
    DEFAULT_EFFORT_N_M,
    MAX_HARMONICS,
    SELF_CLEARANCE_M,
    ExcitationDesign,
    design_excitation,
)
from mbctl.robots.collision import geom_label
from mbctl.robots.commands import Command
from mbctl.robots.edits import position_to_motor
from mbctl.robots.g1 import is_menagerie_g1
from mbctl.robots.identification import model_fingerprint
from mbctl.robots.identification.threads import single_threaded_blas
from mbctl.robots.interface import RobotState
from mbctl.robots.model_pair import Robot
from mbctl.robots.registry import load_robot
from mbctl.sim.monitor import PlantMonitor
from mbctl.sim.simulator import Simulator

#: Length [s] of an excitation unless asked otherwise.
DEFAULT_DURATION_S = 30.0
#: Computed-torque gains of the fixed-base excitation: natural frequency [rad/s], damping ratio.
TRACKING_OMEGA_RAD_S = 30.0
TRACKING_ZETA = 1.0
#: Highest harmonic [Hz] an excitation may ask for: the tracking's natural frequency (30 rad/s,
#: 4.77 Hz), far below the 2-ms control rate's Nyquist (250 Hz). Above it the joints do not follow
#: the design, and the speed limit leaves it no amplitude. Period >= harmonics / 4.77 Hz.
MAX_EXCITATION_HZ = TRACKING_OMEGA_RAD_S / (2.0 * np.pi)
#: What the summary says when the controller has its own model.
SAME_TRAJECTORY = ("trajectory designed on the robot's own model, the same for any --controller-model "
                   "(tracking errors compare like for like)")


@dataclass(frozen=True)
class ExciteParams:
    """What ``mbctl excite`` runs (field names are the CLI options).

    Attributes:
        robot: Known robot name or MJCF file.
        duration: Simulated time [s] (None: 30 s).
        seed: Seed of the excitation design's random start.
        period: Period of the Fourier series' fundamental [s]; at least harmonics /
            :data:`MAX_EXCITATION_HZ`.
        harmonics: Harmonics per joint, 1 to :data:`~mbctl.planners.excitation.MAX_HARMONICS`.
        gravity: Switch on the robot's gravity (the 2-link arm's, in its plane).
        scene: Scene MJCF for MuJoCo that includes the robot.
        model_dir: Explicit Menagerie folder (the G1).
        models: Hidden plant changes and the controller's model.
        plant: In-process (default, optionally through a link model) or the G1 over DDS.
    """

    robot: str
    duration: float | None = None
    seed: int = 0
    period: float = 5.0
    harmonics: int = 5
    gravity: bool = True
    scene: str | None = None
    model_dir: str | None = None
    models: ModelOptions = ModelOptions()
    plant: PlantOptions = PlantOptions()

    def __post_init__(self) -> None:
        self.plant.check_models(self.models)
        if self.duration is not None and not (np.isfinite(self.duration) and self.duration > 0):
            raise ControllerSetupError(f"duration must be a positive number of seconds; got {self.duration}")
        if not (np.isfinite(self.period) and self.period > 0):
            raise ControllerSetupError(f"period must be a positive number of seconds; got {self.period}")
        if not 1 <= self.harmonics <= MAX_HARMONICS:
            raise ControllerSetupError(
                f"--harmonics must be 1 to {MAX_HARMONICS}; got {self.harmonics} (more harmonics only slow "
                "the design: the condition number stops falling past about 5)")
        highest = self.harmonics / self.period
        if highest > MAX_EXCITATION_HZ:
            raise ControllerSetupError(
                f"--period {self.period:g} s with {self.harmonics} harmonics puts the highest harmonic at "
                f"{highest:.3g} Hz; the joints follow up to {MAX_EXCITATION_HZ:.3g} Hz (the tracking's "
                f"{TRACKING_OMEGA_RAD_S:g} rad/s): give --period >= "
                f"{self.harmonics / MAX_EXCITATION_HZ:.3g} s or fewer harmonics")
        if self.seed < 0:
            raise ControllerSetupError(f"seed must be >= 0; got {self.seed}")


def log_section(params: ExciteParams, robot: Robot, joints: tuple[str, ...], bodies: tuple[str, ...],
                period_s: float, excitation: dict[str, Any], measured: bool = True) -> dict[str, Any]:
    """The report's ``identification_log`` section (see :mod:`mbctl.jobs.ident_log`).

    ``robot``: the robot's own model (the one the section names, whose fingerprint identify checks),
    not a ``--controller-model``.

    ``measured``: the plant measured the torques and contacts (in-process); False over DDS, where
    the log holds what the controller commanded.
    """
    source = "measured" if measured else "commanded"
    return {
        "interface": params.plant.interface, "torques": TORQUES[source], "contacts": CONTACTS[source],
        "robot": params.robot, "scene": params.scene, "gravity": params.gravity,
        "model_dir": params.model_dir, "gravity_m_s2": [float(g) for g in robot.mj_model.opt.gravity],
        "model_fingerprint": model_fingerprint(robot), "joints": list(joints),
        "q_columns": q_columns(robot), "v_columns": v_columns(robot), "contact_bodies": list(bodies),
        "timestep_s": robot.timestep_s, "control_period_s": period_s, "csv": CSV_NAME,
        "excitation": excitation,
    }


def prepare(params: ExciteParams, robot: Robot | None = None) -> Work:
    """Load the robot, check it can be excited, design the excitation (no output yet).

    Raises:
        ControllerSetupError: A floating-base robot other than the Menagerie G1, or unactuated joints.
        ToolkitError: Unknown robot, bad plant options, an infeasible design.
    """
    loaded = robot or load_robot(params.robot, params.scene, gravity=params.gravity,
                                 model_dir=params.model_dir)
    if is_menagerie_g1(loaded):
        from mbctl.jobs.excite_g1 import prepare_g1

        return prepare_g1(params, loaded)
    if params.plant != PlantOptions():
        raise ControllerSetupError(
            f"the plant options (--interface, the link, --estimate) are the G1's; {loaded.name!r} is excited "
            "in-process only")
    if loaded.has_floating_base:
        raise ControllerSetupError(
            f"{loaded.name!r} has a floating base; excite runs fixed-base robots (computed torque on a "
            "Fourier excitation) and the Menagerie G1 on its feet (whole-body control)")

    def to_torque(r: Robot) -> Robot:
        kinds = {a.kind for a in r.actuators.values()}
        return position_to_motor(r) if kinds & {"position", "velocity"} else r

    nominal = to_torque(loaded)  # the design's model: the robot's own, whatever the controller uses
    models = build_models(nominal, params.models, to_torque)
    joints = tuple(dict.fromkeys(a.joint for a in nominal.actuators.values() if a.joint))
    unactuated = [j for j, layout in nominal.joints.items() if j not in joints]
    if unactuated or not joints:
        raise ControllerSetupError(f"excite needs every joint actuated; {unactuated or 'all'} are not "
                                   f"({nominal.name!r})")
    q_start = nominal.keyframe_q(nominal.keyframes[0]) if nominal.keyframes else nominal.neutral_q()
    design = design_excitation(nominal, joints, q_start, period_s=params.period, harmonics=params.harmonics,
                               seed=params.seed)
    duration = params.duration or DEFAULT_DURATION_S

    def work(ctx: RunContext) -> Outcome:
        with single_threaded_blas():  # small matrices: threads only cost (robots/identification/threads)
            return _run_fixed(ctx, params, nominal, models, joints, q_start, design, duration)

    return work


def _run_fixed(ctx: RunContext, params: ExciteParams, nominal: Robot, models: Models, joints: tuple[str, ...],
               q_start: np.ndarray, design: ExcitationDesign, duration: float) -> Outcome:
    plant = models.plant
    sim = ctx.attach(Simulator(plant))
    sim.reset(q=q_start)
    ct = ComputedTorque(plant, gains_from_frequency(TRACKING_OMEGA_RAD_S, TRACKING_ZETA), joints,
                        pin_model=models.controller_model)
    # what the log records, measured by the plant each period: the actuators' torques and the
    # contacts on the robot (a fixed-base robot has no contact it is meant to have)
    monitor = PlantMonitor(sim, joints=joints, count_elsewhere=True).attach()
    traj = design.trajectory
    dt = sim.control_period_s
    n = max(1, int(round(duration / dt)))
    reference = traj.trajectory(dt, n * dt)  # one sample past the last cycle: every cycle's v and a
    excitation = {"kind": "Fourier series, computed torque", "period_s": traj.period_s,
                  "harmonics": traj.harmonics, "max_frequency_hz": traj.max_frequency_hz,
                  "condition_number": design.condition_number,
                  "initial_condition_number": design.initial_condition_number,
                  "structural_rank": design.structural_rank, "limit_use_q_v_tau": design.limit_use.tolist(),
                  "tracking": {"omega_rad_s": TRACKING_OMEGA_RAD_S, "zeta": TRACKING_ZETA},
                  "self_clearance": {"pairs": list(design.self_pairs), "kept_m": SELF_CLEARANCE_M,
                                     "min_m": design.min_clearance_m},
                  "assumed_torque_limit_N_m": _assumed_limits(design)}
    excitation["designed_on"] = "the robot's own model (not --controller-model)"
    ctx.sections[SECTION] = log_section(params, nominal, joints, (), dt, excitation)
    ctx.sections["plant"] = models.section()
    csv = ctx.open_csv(header(plant, joints, ()), CSV_NAME)
    ctx.progress.start(n, f"excite {params.robot}")
    tau_log = np.empty((n, len(joints)))
    others = 0
    touched: dict[str, int] = {}  # geom pair label -> rows it was in contact

    def on_step(k: int, state: RobotState, ref: object, command: Command) -> None:
        nonlocal others
        csv.write(log_row(state, monitor))
        tau_log[k] = monitor.joint_torques
        if monitor.contacts_elsewhere > 0:
            others += 1
            for label in _contact_pairs(sim):
                touched[label] = touched.get(label, 0) + 1
        ctx.progress.advance()

    log = run(sim, ct, reference, n * dt, on_step)
    idx_q = [plant.joint(j).idx_q for j in joints]
    q_ref, q_log = log.reference, log.q[:, idx_q]  # the loop log's rows, for the plot
    ctx.values.update({"duration_s": n * dt, "rows": n, "condition_number": design.condition_number,
                       "joint_rms_error_rad": log.error_sums().rms_all(),  # every cycle
                       "max_torque_N_m": dict(zip(joints, np.abs(tau_log).max(0).tolist(), strict=True)),
                       "samples_with_other_contacts": int(others),
                       "contact_rows": {"count": int(others), "fraction": others / n, "geom_pairs": touched}})
    _plot(ctx, log.cycle * dt, joints, q_ref, q_log, tau_log[log.cycle], design)
    lines = [f"excite {params.robot}: {n * dt:g} s of a {traj.harmonics}-harmonic Fourier excitation "
             f"(period {traj.period_s:g} s), regressor condition number {design.condition_number:.3g} "
             f"(random start {design.initial_condition_number:.3g}); tracking RMS "
             f"{ctx.values['joint_rms_error_rad']:.2e} rad",
             f"log: {n} rows in {CSV_NAME}; identify it with: mbctl identify {ctx.output_dir}"]
    lines[1:1] = _contact_lines(others, n, touched) + _limit_lines(design)
    if params.models.hidden or params.models.controller_model:
        lines.insert(1, models_line(models.section())
                     + (f"; {SAME_TRAJECTORY}" if params.models.controller_model else ""))
    return Outcome(True, tuple(lines))


def _contact_pairs(sim: Simulator) -> set[str]:
    """Labels ``"geom_a/geom_b"`` of the contacts touching the robot now.

    Collision-layer names, the lower geom id first (as the collision layer's pairs).
    """
    m, d = sim.model, sim.data
    mine = {int(b) for b in sim.robot.robot_body_ids}
    out = set()
    for c in d.contact[: d.ncon]:
        g1, g2 = sorted((int(c.geom1), int(c.geom2)))
        if int(m.geom_bodyid[g1]) in mine or int(m.geom_bodyid[g2]) in mine:
            out.add(f"{geom_label(m, g1)}/{geom_label(m, g2)}")
    return out


def _contact_lines(rows: int, n: int, touched: dict[str, int]) -> list[str]:
    """The summary's line on rows with a contact on the robot (none: no line)."""
    if not rows:
        return []
    pairs = ", ".join(f"{k} {v}" for k, v in sorted(touched.items(), key=lambda kv: -kv[1])[:4])
    return [f"contacts: the robot touched itself or its scene in {rows} of {n} rows "
            f"({100.0 * rows / n:.1f} %; rows per geom pair: {pairs}); identify leaves those rows out, with "
            "0.1 s around each"]


def _assumed_limits(design: ExcitationDesign) -> dict[str, float]:
    """Joint -> the torque limit [N m] the design assumed because the model gives none."""
    defaulted = design.limits.defaulted_effort if design.limits is not None else ()
    return {j: DEFAULT_EFFORT_N_M for j in defaulted}


def _limit_lines(design: ExcitationDesign) -> list[str]:
    """The summary's line on assumed torque limits (none assumed: no line)."""
    assumed = _assumed_limits(design)
    if not assumed or design.limits is None:
        return []
    kept = float(design.limits.tau_max[list(design.trajectory.names).index(next(iter(assumed)))])
    return [f"torque limits: {', '.join(assumed)} have none in the model (no actuator ctrlrange or "
            f"forcerange, no joint actuatorfrcrange): the design assumed {DEFAULT_EFFORT_N_M:g} N m "
            f"and kept its torques within {kept:g} N m; give the actuators a ctrlrange to set them"]


def _plot(ctx: RunContext, t: np.ndarray, joints: tuple[str, ...], q_ref: np.ndarray, q: np.ndarray,
          tau: np.ndarray, design: ExcitationDesign) -> None:
    """Joint angles (reference dashed, plant solid) and the applied torques, same colours."""
    shown = list(range(min(len(joints), 8)))
    colors = joint_colors([joints[i] for i in shown])
    fig, axes = new_figure(2, 1, (12.0, 7.0), layout="constrained")
    ax_q, ax_tau = axes[0][0], axes[1][0]
    for i in shown:
        c = colors[joints[i]]
        ax_q.plot(t, q_ref[:, i], "--", color=c, lw=1.0)
        ax_q.plot(t, q[:, i], color=c, lw=1.2, label=joints[i])
        ax_tau.plot(t, tau[:, i], color=c, lw=1.0)
    ax_q.set_ylabel("joint angle (rad)")
    ax_q.set_title(f"excitation (dashed: reference; solid: plant), condition number "
                   f"{design.condition_number:.3g}", fontsize=10)
    ax_q.legend(fontsize=8, loc="upper right")
    ax_tau.set_ylabel("applied torque (N m)")
    ax_tau.set_xlabel("time (s)")
    for ax in (ax_q, ax_tau):
        ax.grid(True, alpha=0.3)
    ctx.save_figure(fig, "excite.png")


#: The ``mbctl excite`` job.
EXCITE = Job("excite", prepare)
