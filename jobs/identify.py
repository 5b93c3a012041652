"""``mbctl identify RUN_DIR [RUN_DIR ...]``: the robot's parameters from excitation logs, written back.

Reads each run's identification log (:mod:`mbctl.jobs.ident_log`), loads the nominal robot the
log names (or ``--robot``), and runs :func:`mbctl.robots.identification.identify`: Pinocchio's
joint-torque regressor, contacts projected out (joint torques only) or the measured wrenches,
the identifiability report, the physically consistent estimate regularised toward the nominal
model, and the validation on the last part of each log. Everything that can make a log unusable
(too short, not exciting, NaN, non-increasing time, another robot's, columns missing, recorded on
another model, torques against the nominal model's sign) is found before any output (exit 2).
A log recorded on a model other than the one identified (its dynamics fingerprint differs, or it
has none) is refused unless ``--allow-other-model`` says so; the report records that it did.
The run folder gets:

* ``identify_report.json``: per body ``mass_kg``, ``com_m`` (each ``nominal``, ``identified``,
  ``std``) and the inertia; per joint friction and armature when asked; the identifiability
  (rank, condition number, base parameters, and why each unidentified parameter is not); and
  ``validation`` with ``torque_rmse_nominal`` and ``torque_rmse_identified`` [N m].
* ``identified.xml``: the robot's MJCF with the identified values, loaded back as a robot and
  cross-checked (both engines) before the job reports success.
* ``identify.csv``: validation torques per joint, measured and predicted by both models;
  ``identify.png``: the same, plotted.

Exit 1 when the identified model predicts the validation torques worse than the nominal one
(by more than :data:`WORSE_RTOL`: equal within the noise floor is not worse), or when the
written model fails its round trip or cross-check.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from mbctl.jobs.ident_log import CONTACTS, TORQUES, read_run
from mbctl.jobs.recording import q_columns
from mbctl.jobs.runner import Job, Outcome, RunContext, Work
from mbctl.robots.crosscheck import crosscheck
from mbctl.robots.identification import (
    BadLogError,
    Identification,
    IdentifyOptions,
    add_noise,
    identified_xml,
    identify,
    model_fingerprint,
)
from mbctl.robots.identification.identifiability import reasons
from mbctl.robots.identification.parameters import ParameterSet
from mbctl.robots.identification.summary import base_summaries, body_summary, joint_summaries
from mbctl.robots.model_pair import Robot
from mbctl.robots.registry import load_robot
from mbctl.sim.atomic import write_json_atomic, write_text_atomic

REPORT_NAME = "identify_report.json"
MODEL_NAME = "identified.xml"
#: Relative agreement of the written model's parameters with the estimate (MuJoCo writes 6 digits).
ROUND_TRIP_RTOL = 1e-4
#: Cross-check states of the identified model.
XCHECK_STATES = 30
#: The identified validation RMSE counts as worse than the nominal one only above ``1 + WORSE_RTOL``
#: times it: on a log the nominal model already fits (an exact log of the exact model) both sit at
#: the noise floor of the samples' differenced accelerations and filter, and differ there by
#: fractions of a percent either way.
WORSE_RTOL = 0.01
#: A joint whose measured torques have a cosine similarity below this with the nominal model's
#: (over the validation rows) runs against the model: a sign-flipped torque column, or another
#: robot's log. Gross mass errors keep it near +1; a flip gives about -1.
MIN_TORQUE_COSINE = -0.5


@dataclass(frozen=True)
class IdentifyParams:
    """What ``mbctl identify`` runs (field names are the CLI options).

    Attributes:
        runs: Run folders of ``mbctl excite``.
        robot: Nominal robot (name or MJCF); default: the one the logs name.
        bodies: Bodies to identify (empty: every body with mass that moves).
        friction: Identify viscous and Coulomb friction per actuated joint.
        armature: Identify armature per actuated joint.
        contact: "projected" (joint torques only) or "measured" (the logs' contact wrenches).
        cutoff: Low-pass cutoff [Hz] (0: no filter).
        rate: Decimation rate [Hz] (0: every sample).
        validation: Last fraction of each log kept for validation.
        torque_noise: Study: white torque noise, % of each joint's RMS torque.
        encoder_noise: Study: white encoder noise [rad] (and its difference on v).
        seed: Seed of the noise and of the structural states.
        model_dir: Explicit Menagerie folder (the G1).
        allow_other_model: Identify from logs recorded on another model (another dynamics
            fingerprint, or none) than the nominal one; recorded in the report.
    """

    runs: tuple[str, ...]
    robot: str | None = None
    bodies: tuple[str, ...] = ()
    friction: bool = False
    armature: bool = False
    contact: str = "projected"
    cutoff: float = 10.0
    rate: float = 100.0
    validation: float = 0.25
    torque_noise: float = 0.0
    encoder_noise: float = 0.0
    seed: int = 0
    model_dir: str | None = None
    allow_other_model: bool = False

    def __post_init__(self) -> None:
        if not self.runs:
            raise BadLogError("give at least one run folder of mbctl excite")
        for name in ("cutoff", "rate", "torque_noise", "encoder_noise"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise BadLogError(f"{name.replace('_', '-')} must be a finite number >= 0; got {value}")
        if not 0 < self.validation <= 0.9:
            raise BadLogError(f"validation must be a fraction in (0, 0.9]; got {self.validation}")

    @property
    def options(self) -> IdentifyOptions:
        """The library's options."""
        return IdentifyOptions(self.bodies or None, self.friction, self.armature, self.contact,
                               self.cutoff or None, self.rate or None, self.validation, seed=self.seed)


def load_nominal(params: IdentifyParams, section: dict[str, Any]) -> Robot:
    """The nominal robot: ``--robot``, else the one the log names, with the log's gravity."""
    name = params.robot or section["robot"]
    scene = section.get("scene") if params.robot is None else None
    robot = load_robot(name, scene, gravity=bool(section.get("gravity")) or None,
                       model_dir=params.model_dir or section.get("model_dir"))
    logged = np.asarray(section.get("gravity_m_s2", robot.mj_model.opt.gravity), dtype=float)
    if not np.allclose(logged, robot.mj_model.opt.gravity):
        g = logged.copy()

        def set_gravity(spec: Any) -> None:
            spec.option.gravity = g

        robot = robot.with_edits(f"gravity set to the log's {g.tolist()} m/s^2", mj_edit=set_gravity)
    return robot


def check_same_robot(robot: Robot, section: dict[str, Any], run: str) -> None:
    """The log's coordinates must be the robot's.

    Raises:
        BadLogError: Another robot's log (names both).
    """
    if list(section["q_columns"]) != q_columns(robot):
        theirs = section.get("robot", "?")
        raise BadLogError(f"{run} is a log of {theirs!r}; its coordinates ({len(section['q_columns'])} "
                          f"q columns, first {section['q_columns'][:2]}) are not {robot.name!r}'s "
                          f"({robot.nq} q, first {q_columns(robot)[:2]}): another robot's log")


def short(fingerprint: str | None) -> str:
    """The first 12 hex digits of a fingerprint (what messages show), or "none"."""
    return fingerprint[:12] if isinstance(fingerprint, str) and fingerprint else "none"


def check_recorded_model(robot: Robot, fingerprint: str, sections: list[dict[str, Any]],
                         runs: tuple[str, ...], allow_other_model: bool) -> None:
    """Each log must have been recorded on the model being identified (same dynamics fingerprint).

    The same joint names are not the same arm: another arm's log fits its own masses, which the
    estimate then reports as this robot's.

    Raises:
        BadLogError: A log whose fingerprint differs or is missing, without ``allow_other_model``
            (names each such run and both fingerprints).
    """
    other = [(run, s.get("model_fingerprint")) for run, s in zip(runs, sections, strict=True)
             if s.get("model_fingerprint") != fingerprint]
    if not other or allow_other_model:
        return
    same = [run for run, s in zip(runs, sections, strict=True) if s.get("model_fingerprint") == fingerprint]
    listed = "; ".join(f"{run} was recorded on {short(fp)}" if fp else
                       f"{run} records no model fingerprint (not an mbctl excite log of this version)"
                       for run, fp in other)
    raise BadLogError(
        f"the log's model is not the model being identified, {robot.name!r} (fingerprint {short(fingerprint)}"
        + (f", as in {', '.join(same)}" if same else "") + f"): {listed}; another arm with the same joint "
        "names gives wrong parameters. Identify each log with the robot it was recorded on (--robot, "
        "default: the one the first log names), or pass --allow-other-model to use it anyway (recorded "
        "in identify_report.json)")


def check_torque_sign(ident: Identification) -> None:
    """The measured torques must run with the nominal model's prediction, joint by joint.

    Raises:
        BadLogError: A joint whose torques' cosine similarity with the nominal prediction (over the
            validation rows) is below :data:`MIN_TORQUE_COSINE`: the estimate would fit a body
            that does not exist (a link of tens of kg with its CoM behind the joint) with a small std.
    """
    pred = ident.nominal_prediction
    m, p = pred.measured, pred.predicted
    norm = np.linalg.norm(m, axis=0) * np.linalg.norm(p, axis=0)
    cosine = np.where(norm > 0, np.sum(m * p, axis=0) / np.where(norm > 0, norm, 1.0), 1.0)
    bad = [(j, c) for j, c in zip(pred.joints, cosine, strict=True) if c < MIN_TORQUE_COSINE]
    if bad:
        listed = ", ".join(f"{j} ({c:+.2f})" for j, c in bad)
        raise BadLogError(
            f"the logged torques run against the nominal model's: cosine similarity of measured and "
            f"predicted torque {listed} (< {MIN_TORQUE_COSINE:g}; a correct log of this robot is near +1, "
            "even with heavy hidden masses); the torque columns' sign is flipped, or the log is not this "
            "robot's. Fix the sign convention of tau_<joint>_N_m (torque on the joint, positive along its "
            "axis); no estimate is written")


def prepare(params: IdentifyParams) -> Work:
    """Read and check every log, identify (errors in the logs exit 2 before any output).

    Raises:
        BadLogError: A log that cannot be identified from (the reason in the message).
        ToolkitError: Unknown robot or bodies.
    """
    logs, sections = [], []
    for run in params.runs:
        log, section = read_run(Path(run))
        logs.append(log)
        sections.append(section)
    robot = load_nominal(params, sections[0])
    for run, section in zip(params.runs, sections, strict=True):
        check_same_robot(robot, section, run)
    fingerprint = model_fingerprint(robot)
    check_recorded_model(robot, fingerprint, sections, params.runs, params.allow_other_model)
    if params.torque_noise or params.encoder_noise:
        logs = [add_noise(robot, log, params.torque_noise, params.encoder_noise, params.seed + k)
                for k, log in enumerate(logs)]
    t0 = time.perf_counter()
    ident = identify(robot, logs, params.options)
    seconds = time.perf_counter() - t0
    check_torque_sign(ident)

    def work(ctx: RunContext) -> Outcome:
        return _write(ctx, params, robot, ident, sections, fingerprint, seconds)

    return work


def _body_entry(ident: Identification, name: str) -> dict[str, Any]:
    body = body_summary(ident, name)
    nom, est = body.nominal, body.identified
    return {"mass_kg": {"nominal": nom.mass_kg, "identified": est.mass_kg, "std": body.mass_std_kg,
                        "status": body.mass_status},
            "com_m": {"nominal": nom.com_m.tolist(), "identified": est.com_m.tolist(),
                      "std": body.com_std_m.tolist(), "status": list(body.com_status)},
            "inertia_kg_m2": {"nominal": nom.inertia_com.tolist(), "identified": est.inertia_com.tolist(),
                              "about": "the CoM, body axes"}}


#: The report's key (with its unit) of each joint parameter of the summary.
JOINT_KEYS = {"viscous": "viscous_N_m_s_rad", "coulomb": "coulomb_N_m", "armature": "armature_kg_m2"}


def _joint_entries(ident: Identification) -> dict[str, Any]:
    return {joint: {JOINT_KEYS[kind]: p._asdict() for kind, p in entry.items()}
            for joint, entry in joint_summaries(ident).items()}


def report_dict(params: IdentifyParams, robot: Robot, ident: Identification, sections: list[dict[str, Any]],
                fingerprint: str, seconds: float) -> dict[str, Any]:
    """The content of ``identify_report.json``."""
    why = reasons(ident.data, ident.structural)
    method = {
        "regressor": "pinocchio.computeJointTorqueRegressor, columns per MuJoCo body (its own frame)",
        "estimate": "MAP: torque misfit / sigma^2 + geometric prior around the nominal model, subject to "
                    "each body's pseudo-inertia > 0 (LMI, log-det barrier Newton method)",
        "contacts": {"none": "fixed base: no contact", "projected": "projected onto the null space of the "
                     "contact Jacobian (joint torques only, no force sensor)",
                     "measured": "measured contact wrenches from the log"}[ident.contact],
        "filter": {"cutoff_hz": params.cutoff or None, "rate_hz": params.rate or None},
        "noise_sigma_N_m": ident.estimate.sigma,
        "solver_iterations": ident.estimate.iterations,
        "consistency_constraints_active": ident.estimate.constrained,
        "std": "residual-aware: Laplace + max(10-segment jackknife, Newey-West) + the filter's and the "
               "time step's systematic terms (robots/identification/uncertainty); status per number: "
               "identified, weakly excited (relative excitation below "
               f"{ident.data.summary()['weak_excitation_below']:g}) or not identified (the prior's)",
    }
    base = [b._asdict() for b in base_summaries(ident)]
    return {
        "robot": robot.name,
        "model_fingerprint": fingerprint,
        "allow_other_model": params.allow_other_model,
        "logs": [{"run": r, "recorded_with_fingerprint": s.get("model_fingerprint"),
                  "same_nominal_model": s.get("model_fingerprint") == fingerprint,
                  "interface": s.get("interface", "sim"), "torques": s.get("torques", TORQUES["measured"]),
                  "contacts": s.get("contacts", CONTACTS["measured"])}
                 for r, s in zip(params.runs, sections, strict=True)],
        "method": method,
        "noise_added": {"torque_pct": params.torque_noise, "encoder_rad": params.encoder_noise,
                        "seed": params.seed} if params.torque_noise or params.encoder_noise else None,
        "samples": {"training": len(ident.training), "validation": len(ident.validation),
                    "excluded_before_decimation": ident.training.excluded},
        "identifiability": {**ident.data.summary(),
                            "structural_rank": ident.structural.rank if ident.structural else None,
                            "not_identified": [{"parameter": k, "reason": v} for k, v in why.items()],
                            "base_parameters": base},
        "bodies": {b.name: _body_entry(ident, b.name) for b in ident.params.bodies},
        "joints": _joint_entries(ident),
        "validation": {
            "torque_rmse_nominal": ident.nominal_prediction.rmse(),
            "torque_rmse_identified": ident.identified_prediction.rmse(),
            "torque_rmse_nominal_by_joint": ident.nominal_prediction.rmse_by_joint(),
            "torque_rmse_identified_by_joint": ident.identified_prediction.rmse_by_joint(),
            "units": "N m",
            "worse_when": f"identified > (1 + {WORSE_RTOL:g}) x nominal (equal within the noise floor is "
                          "not worse)",
            "time_s": [float(ident.validation.t_s.min()), float(ident.validation.t_s.max())],
        },
        "identification_time_s": seconds,
    }


def _round_trip(robot: Robot, ident: Identification, path: Path) -> tuple[float, float]:
    """Load ``identified.xml`` as a robot: (largest relative parameter difference, xcheck max error)."""
    loaded = load_robot(path)
    again = ParameterSet(loaded, [b.name for b in ident.params.bodies])
    err = 0.0
    for b in ident.params.bodies:
        want, got = ident.theta[b.columns], again.body(b.name).nominal
        err = max(err, float(np.abs(got - want).max() / max(np.abs(want).max(), 1e-12)))
    report = crosscheck(loaded, n_states=XCHECK_STATES)
    worst = max((q.max_rel_error for q in report.quantities if np.isfinite(q.max_rel_error)), default=0.0)
    return err, float(worst) if report.passed else float("inf")


def _write(ctx: RunContext, params: IdentifyParams, robot: Robot, ident: Identification,
           sections: list[dict[str, Any]], fingerprint: str, seconds: float) -> Outcome:
    from mbctl.jobs.identify_plots import stream_validation, validation_plot

    report = report_dict(params, robot, ident, sections, fingerprint, seconds)
    stream_validation(ctx, ident)
    model_path = ctx.path(MODEL_NAME, "identified_model")
    write_text_atomic(model_path, identified_xml(robot, ident.params, ident.theta))
    round_trip, xcheck_error = _round_trip(robot, ident, model_path)
    report["identified_model"] = {"file": MODEL_NAME, "round_trip_max_rel_error": round_trip,
                                  "xcheck_max_rel_error": xcheck_error, "xcheck_states": XCHECK_STATES}
    write_json_atomic(ctx.path(REPORT_NAME, "identify_report"), report)
    validation_plot(ctx, ident)
    v = report["validation"]
    ctx.values.update({"torque_rmse_nominal": v["torque_rmse_nominal"],
                       "torque_rmse_identified": v["torque_rmse_identified"],
                       "rank": ident.data.rank, "parameters": ident.params.n,
                       "condition_number": ident.data.condition_number,
                       "identification_time_s": seconds, "round_trip_max_rel_error": round_trip,
                       "xcheck_max_rel_error": xcheck_error,
                       "bodies": {k: {"mass_kg": e["mass_kg"]["identified"],
                                      "com_m": e["com_m"]["identified"]}
                                  for k, e in report["bodies"].items()}})
    better = not worse(v["torque_rmse_nominal"], v["torque_rmse_identified"])
    written = round_trip < ROUND_TRIP_RTOL and np.isfinite(xcheck_error)
    lines = [
        f"identify {robot.name}: {ident.params.n} parameters, rank {ident.data.rank} (structural "
        f"{report['identifiability']['structural_rank']}), condition number "
        f"{ident.data.condition_number:.3g}; "
        f"{len(report['identifiability']['not_identified'])} not identifiable alone (kept at the prior where "
        "the data are silent; reasons in the report)",
        f"validation torque RMSE: nominal {v['torque_rmse_nominal']:.4g} N m, identified "
        f"{v['torque_rmse_identified']:.4g} N m ({report['method']['contacts']}); torques: "
        + "; ".join(sorted({log["torques"].split(" (")[0] for log in report["logs"]})),
        f"identified.xml: parameters round trip {round_trip:.1e}, cross-check max rel. error "
        f"{xcheck_error:.1e} ({XCHECK_STATES} states); identification took {seconds:.2f} s",
    ]
    for name, entry in list(report["bodies"].items())[:4] if len(report["bodies"]) <= 4 else []:
        m = entry["mass_kg"]
        lines.append(f"  {name}: mass {m['nominal']:.4g} -> {m['identified']:.4g} kg (std {m['std']:.2g}"
                     f"{_mark(m['status'])}), CoM {np.round(entry['com_m']['identified'], 4).tolist()} m"
                     + _com_marks(entry["com_m"]["status"]))
    weak = report["identifiability"]["weakly_excited"]
    if weak:
        lines.append(f"weakly excited (the log barely moves them; trust them only within their std): "
                     f"{', '.join(weak[:8])}{' ...' if len(weak) > 8 else ''}")
    others = [log["run"] for log in report["logs"] if not log["same_nominal_model"]]
    if others:
        lines.append(f"--allow-other-model: {', '.join(others)} recorded on another model (or none recorded) "
                     f"than {robot.name!r} ({short(fingerprint)}); identified anyway")
    return Outcome(bool(better and written), tuple(lines),
                   f"identified validation RMSE <= (1 + {WORSE_RTOL:g}) x nominal; identified.xml round trip "
                   "and cross-check pass")


def worse(nominal_rmse: float, identified_rmse: float) -> bool:
    """The identified model predicts worse than the nominal one, beyond :data:`WORSE_RTOL`."""
    return not identified_rmse <= (1.0 + WORSE_RTOL) * nominal_rmse


def _mark(status: str) -> str:
    """``""`` for an identified number, else ``"; weakly excited"`` or ``"; not identified"``."""
    return "" if status == "identified" else f"; {status}"


def _com_marks(statuses: list[str]) -> str:
    """`` (z: weakly excited; y: not identified)`` for the CoM coordinates that are not identified."""
    if len(set(statuses)) == 1:
        return "" if statuses[0] == "identified" else f" ({statuses[0]})"
    parts = [f"{axis}: {s}" for axis, s in zip("xyz", statuses, strict=True) if s != "identified"]
    return f" ({'; '.join(parts)})"


#: The ``mbctl identify`` job.
IDENTIFY = Job("identify", prepare)
