"""Identification from logs, start to end: samples, equations, identifiability, estimate, validation.

``identify(robot, logs, options)`` returns an :class:`Identification`: the parameter set, the
identifiability of the data (and of random states: what no motion could identify), the physically
consistent estimate regularised toward ``robot`` (the nominal model, the prior), and the torque
prediction of both models on the validation part of each log (the last ``validation_fraction`` of
its time), which identification never saw.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np
import pinocchio as pin

from mbctl.robots.identification.estimate import Estimate, estimate
from mbctl.robots.identification.exceptions import BadLogError
from mbctl.robots.identification.identifiability import Identifiability, analyse
from mbctl.robots.identification.parameters import ParameterSet
from mbctl.robots.identification.regressor import TorquePrediction, predict, stack
from mbctl.robots.identification.samples import RecordedLog, Samples, prepare_samples, split
from mbctl.robots.identification.threads import single_threaded_blas
from mbctl.robots.identification.uncertainty import (
    Uncertainty,
    filter_term,
    map_estimate,
    residual_uncertainty,
    shift_term,
)
from mbctl.robots.model_pair import Robot

#: A log whose data rank is below this fraction of the structural rank does not excite the robot.
MIN_EXCITATION = 0.5


@dataclass(frozen=True)
class IdentifyOptions:
    """How to identify.

    Attributes:
        bodies: Bodies to identify (None: every body with mass that moves).
        friction: Identify viscous and Coulomb friction per actuated joint.
        armature: Identify armature per actuated joint.
        contact: "projected" (joint torques only) or "measured" (the log's contact wrenches).
        cutoff_hz: Low-pass cutoff [Hz] (None: no filter, forward differences).
        rate_hz: Decimation rate [Hz] (None: every sample).
        validation_fraction: Last fraction of each log's time kept for validation.
        structural_samples: Random states for the structural identifiability (0: skip).
        seed: Seed of the random states.
    """

    bodies: tuple[str, ...] | None = None
    friction: bool = False
    armature: bool = False
    contact: str = "projected"
    cutoff_hz: float | None = 10.0
    rate_hz: float | None = 100.0
    validation_fraction: float = 0.25
    structural_samples: int = 200
    seed: int = 0


@dataclass(frozen=True)
class Identification:
    """The result of :func:`identify`.

    Attributes:
        params: The parameter set (names, nominal values, bodies, joints).
        estimate: The physically consistent estimate.
        data: Identifiability of the training data.
        structural: Identifiability on random states (what no log could do better), or None.
        training: The training samples.
        validation: The validation samples.
        nominal_prediction: Validation torques predicted by the nominal model.
        identified_prediction: Validation torques predicted by the identified model.
        contact: How contacts were handled ("projected", "measured", or "none": fixed base).
        uncertainty: The residual-aware covariance (:mod:`~mbctl.robots.identification.uncertainty`);
            ``estimate.std`` and ``estimate.covariance`` are its reported ones, its ``laplace`` the
            white-noise covariance.
    """

    params: ParameterSet
    estimate: Estimate
    data: Identifiability
    structural: Identifiability | None
    training: Samples
    validation: Samples
    nominal_prediction: TorquePrediction
    identified_prediction: TorquePrediction
    contact: str
    uncertainty: Uncertainty | None = None

    @property
    def theta(self) -> np.ndarray:
        """The identified parameters (n,)."""
        return self.estimate.theta


def model_fingerprint(robot: Robot) -> str:
    """SHA-256 of the robot's dynamics, so a log can tell which nominal model recorded it.

    Joint names, types, placements, inertias, armature, friction and gravity; not actuators,
    sites or meshes.
    """
    model = robot.pin_model
    h = hashlib.sha256()
    for j in range(1, model.njoints):
        h.update(model.names[j].encode())
        h.update(model.joints[j].shortname().encode())
        h.update(np.round(model.jointPlacements[j].homogeneous, 12).tobytes())
        h.update(np.round(model.inertias[j].toDynamicParameters(), 12).tobytes())
    for arr in (model.armature, model.damping, model.upperDryFrictionLimit, model.gravity.linear):
        h.update(np.round(np.asarray(arr, dtype=float), 12).tobytes())
    return h.hexdigest()


def concatenate(parts: Sequence[Samples]) -> Samples:
    """The samples of several logs as one set (equations are per sample; order does not matter)."""
    first = parts[0]
    if len(parts) == 1:
        return first
    bodies = first.contact_bodies
    for p in parts[1:]:
        if p.contact_bodies != bodies:
            raise BadLogError(f"logs with different contact bodies ({bodies} and {p.contact_bodies}) "
                              "cannot be identified together")
    wrenches = None
    if all(p.wrenches is not None for p in parts):
        wrenches = np.concatenate([p.wrenches for p in parts])  # type: ignore[misc]
    excluded: dict[str, int] = {}
    for p in parts:
        for k, v in p.excluded.items():
            excluded[k] = excluded.get(k, 0) + v
    return replace(first, t_s=np.concatenate([p.t_s for p in parts]), q=np.concatenate([p.q for p in parts]),
                   v=np.concatenate([p.v for p in parts]), a=np.concatenate([p.a for p in parts]),
                   tau=np.concatenate([p.tau for p in parts]),
                   contacts=np.concatenate([p.contacts for p in parts]), wrenches=wrenches, excluded=excluded)


def structural_samples(robot: Robot, like: Samples, n: int, seed: int) -> Samples:
    """``n`` random states with the contact patterns of ``like``'s samples.

    q within the joint limits, v and a standard normal: what the equations of any motion could
    identify.
    """
    model = robot.pin_model
    rng = np.random.default_rng(seed)
    lo = np.where(np.isfinite(model.lowerPositionLimit), model.lowerPositionLimit, -np.pi).clip(-np.pi, np.pi)
    hi = np.where(np.isfinite(model.upperPositionLimit), model.upperPositionLimit, np.pi).clip(-np.pi, np.pi)
    q = np.array([_random_q(model, lo, hi, rng) for _ in range(n)])
    v = rng.standard_normal((n, model.nv))
    a = rng.standard_normal((n, model.nv))
    pick = rng.integers(0, len(like), n)
    return Samples(np.arange(n, dtype=float), q, v, a, np.zeros((n, model.nv)), like.contacts[pick],
                   like.contact_bodies, None if like.wrenches is None else like.wrenches[pick])


def _random_q(model: pin.Model, lo: np.ndarray, hi: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    q = rng.uniform(lo, hi)
    for j in range(1, model.njoints):
        joint = model.joints[j]
        if joint.nq != joint.nv:  # a quaternion (free-flyer or ball): a random unit quaternion
            quat = rng.standard_normal(4)
            q[joint.idx_q + joint.nq - 4:joint.idx_q + joint.nq] = quat / np.linalg.norm(quat)
    return q


def identify(robot: Robot, logs: Sequence[RecordedLog], options: IdentifyOptions | None = None
             ) -> Identification:
    """Identify ``robot``'s parameters from ``logs`` (see the module docstring).

    Raises:
        BadLogError: A log that is too short, not finite, another robot's, or does not excite the
            robot (its rank is below :data:`MIN_EXCITATION` of the structural rank).
        IdentificationError: Unknown bodies or contact mode, or the solver failed.
    """
    with single_threaded_blas():
        return _identify(robot, logs, options or IdentifyOptions())


def _identify(robot: Robot, logs: Sequence[RecordedLog], options: IdentifyOptions) -> Identification:
    params = ParameterSet(robot, options.bodies, options.friction, options.armature)
    trains, vals = [], []
    for log in logs:
        samples = prepare_samples(robot, log, options.cutoff_hz, options.rate_hz)
        train, val = split(samples, options.validation_fraction)
        trains.append(train)
        vals.append(val)
    training, validation = concatenate(trains), concatenate(vals)
    contact = options.contact if training.contacts.shape[1] else "none"
    mode = "projected" if contact == "none" else contact
    system = stack(params, training, mode)
    scale = params.prior_std()
    data = analyse(system, params.names, scale)
    structural = None
    if options.structural_samples:
        random = structural_samples(robot, training, options.structural_samples, options.seed)
        structural = analyse(stack(params, random, "projected"), params.names, scale)
        if data.rank < MIN_EXCITATION * structural.rank:
            moved = float(np.abs(training.v).max()) if len(training) else 0.0
            raise BadLogError(
                f"the log does not excite the robot: its equations have rank {data.rank} of the "
                f"{structural.rank} any motion could reach (largest speed {moved:.3g} rad/s); record "
                "an excitation (mbctl excite)")
    result = estimate(params, system, data.rank)
    theta_map = map_estimate(params, system, result.sigma)
    shifted = concatenate([replace(t, v=t.v + t.a * log.dt_s) for t, log in zip(trains, logs, strict=True)])
    step = shift_term(theta_map, map_estimate(params, stack(params, shifted, mode), result.sigma))
    honest = residual_uncertainty(params, training, mode, result,
                                  _filter_covariance(robot, logs, options, params, mode, theta_map, result),
                                  step)
    result = replace(result, std=honest.std, covariance=honest.covariance)
    joints = tuple(j.name for j in robot.joints.values() if j.nv == 1 and _actuated(robot, j.name))
    nominal, identified = predict(params, [params.nominal, result.theta], validation, joints, mode)
    return Identification(params, result, data, structural, training, validation, nominal, identified,
                          contact, honest)


def _filter_covariance(robot: Robot, logs: Sequence[RecordedLog], options: IdentifyOptions,
                       params: ParameterSet, mode: str, theta_map: np.ndarray, result: Estimate
                       ) -> np.ndarray | None:
    """The filter's systematic term: the fit again at twice the cutoff (None: no filter, or no room)."""
    if not options.cutoff_hz:
        return None
    doubled = 2.0 * options.cutoff_hz
    if any(doubled >= 0.45 / log.dt_s for log in logs):  # no room below the Nyquist frequency
        return None
    trains = [split(prepare_samples(robot, log, doubled, options.rate_hz), options.validation_fraction)[0]
              for log in logs]
    again = stack(params, concatenate(trains), mode)
    return filter_term(theta_map, map_estimate(params, again, result.sigma))


def _actuated(robot: Robot, joint: str) -> bool:
    return any(a.joint == joint for a in robot.actuators.values())


def base_parameter_errors(base: Sequence[Mapping[str, float]], identified: Sequence[float],
                          truth: Mapping[str, float]) -> np.ndarray:
    """Relative errors of identified base parameters against a hidden truth (studies, tests).

    Args:
        base: Each base parameter's coefficients (parameter name -> coefficient), as in
            :class:`~mbctl.robots.identification.identifiability.BaseParameter` and the report.
        identified: The identified value of each.
        truth: The true value of every parameter the coefficients name.

    Returns:
        Per base parameter ``|identified - true| / reference``: the reference is its true value,
        or, when that is smaller (a first moment that is zero across the link, say), the largest
        true value among the base parameters of the same kind (masses, first moments, inertias),
        so a zero-valued one is judged on the scale of its kind rather than on nothing.
    """
    def kind(b: Mapping[str, float]) -> str:
        lead = next(iter(b)).rsplit(".", 1)[-1]
        return "m" if lead == "m" else lead[:2]

    true = np.array([sum(c * truth[n] for n, c in b.items()) for b in base])
    kinds = [kind(b) for b in base]
    scale = {k: max(abs(t) for t, kk in zip(true, kinds, strict=True) if kk == k) for k in set(kinds)}
    ref = np.array([max(abs(t), scale[k], 1e-300) for t, k in zip(true, kinds, strict=True)])
    return np.abs(np.asarray(identified, dtype=float) - true) / ref
