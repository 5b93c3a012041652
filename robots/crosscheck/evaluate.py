"""Cross-validation of the dynamics of a robot's Pinocchio model against its MuJoCo plant.

Over many states ``(q, v, tau, a)`` the same quantities are evaluated by both engines and
compared in one convention, Pinocchio's (free-flyer quaternion (x, y, z, w), base velocity
``v_WB_B`` in the base frame), through the model pair's ``StateConverter``:

* forward kinematics ``X_WF`` of every body and site F (position ``p_WF`` [m], rotation
  ``R_WF`` [-]);
* frame Jacobians ``J_WF`` (6, nv) in LOCAL_WORLD_ALIGNED (linear velocity of F's origin and
  angular velocity, world axes): Pinocchio's ``getFrameJacobian`` against ``mj_jacBody`` /
  ``mj_jacSite`` mapped through ``T(q)``; centre of mass ``p_WC`` and its Jacobian;
* ``M(q)`` with armature, gravity ``g(q)``, bias ``b(q, v)`` (including the term the free-flyer
  velocity frame adds);
* forward dynamics (Pinocchio ABA against MuJoCo's ``qacc``) and inverse dynamics (RNEA against
  ``mj_inverse``);
* kinetic and potential energy; centroidal momentum against MuJoCo's subtree momentum. The
  kinetic energy is ``1/2 v^T M v`` with armature on both sides: MuJoCo's ``energy[1]`` (armature
  in its M); Pinocchio's ``computeKineticEnergy`` of the rigid bodies plus
  ``1/2 v^T diag(armature) v`` (Pinocchio 4.1 leaves the armature of unaligned revolute joints out
  of its own energy).

MuJoCo runs on a private copy of the plant with everything outside rigid-body dynamics switched
off (see ``plant.comparison_model``); the report says what that was and what could not be compared.

Errors: for a quantity with Pinocchio values ``a_s`` and MuJoCo values ``b_s`` over states s,
``abs = max_s max_i |a_si - b_si|`` and ``rel = abs / max(max_s max_i |b_si|, floor)``. The
denominator is the quantity's magnitude over the whole run, not per state, so a state where a
quantity is small by cancellation (a potential energy near zero) does not inflate the error; the
floor only binds when the quantity is (nearly) zero in every state (gravity with gravity off).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping

import numpy as np

from mbctl.robots.agreement import check_agreement
from mbctl.robots.crosscheck.evaluator import CHUNK_SIZE, Evaluator
from mbctl.robots.crosscheck.exceptions import CrossCheckError
from mbctl.robots.crosscheck.frames import match_frames
from mbctl.robots.crosscheck.locate import describe_entry, dof_labels
from mbctl.robots.crosscheck.plant import comparison_model
from mbctl.robots.crosscheck.report import (
    FAIL,
    NOT_COMPARED,
    PASS,
    FeatureNote,
    QuantityResult,
    Report,
)
from mbctl.robots.crosscheck.sampling import Sampling, sample_states
from mbctl.robots.crosscheck.structure import first as _first
from mbctl.robots.crosscheck.structure import located_differences, structure_problems
from mbctl.robots.crosscheck.tolerances import TOLERANCES, Tolerance
from mbctl.robots.exceptions import ModelMismatchError
from mbctl.robots.model_pair import Robot

_DEFAULT_SAMPLING = Sampling()


def _validate(n_states: object, seed: object) -> None:
    if isinstance(n_states, bool) or not isinstance(n_states, (int, np.integer)) or n_states < 0:
        raise CrossCheckError(f"n_states must be an integer >= 0; got {n_states!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise CrossCheckError(f"seed must be an integer >= 0; got {seed!r}")


def crosscheck(
    robot: Robot,
    n_states: int = 100,
    seed: int = 0,
    *,
    tolerances: Mapping[str, Tolerance] = TOLERANCES,
    sampling: Sampling = _DEFAULT_SAMPLING,
    chunk_size: int = CHUNK_SIZE,
    progress: Callable[[int, int], None] | None = None,
) -> Report:
    """Compare the dynamics of ``robot.pin_model`` with ``robot.mj_model`` over many states.

    Args:
        robot: The model pair (may be loaded with ``check=False`` and a different Pinocchio file).
        n_states: Number of random states; edge states (zero velocity, joints at their limits)
            are added on top.
        seed: Seed of the random states.
        tolerances: Pass criterion per quantity; must name every quantity in ``TOLERANCES``.
        sampling: Ranges and scales of the random states.
        chunk_size: States evaluated between two batched conversions and error reductions
            (``evaluator.CHUNK_SIZE``, chosen by measurement on the G1).
        progress: Called as ``progress(done_states, total_states)`` after each chunk of
            ``chunk_size`` states, with ``done_states`` increasing up to ``total_states``
            (random plus edge states, ``Report.n_states``); for progress bars. It runs inside the
            timed evaluation, so keep it cheap. None: no calls. Not called when no state is
            evaluated (the joint layouts differ or the robot has no degrees of freedom).

    Returns:
        The report: per quantity max abs and relative error, tolerance, worst state and status
        (for a failing quantity also the entry where it fails worst: frame, joint, axis); the
        model features left out and why; notes (load-time agreement check, unmatched frames).

    Raises:
        CrossCheckError: ``n_states`` or ``seed`` not a non-negative integer, ``chunk_size`` < 1,
            ``tolerances`` missing a quantity, or ``progress`` neither callable nor None.
    """
    _validate(n_states, seed)
    if isinstance(chunk_size, bool) or not isinstance(chunk_size, (int, np.integer)) or chunk_size < 1:
        raise CrossCheckError(f"chunk_size must be an integer >= 1; got {chunk_size!r}")
    if progress is not None and not callable(progress):
        raise CrossCheckError(
            f"progress must be a callable progress(done_states, total_states) or None; got {progress!r}"
        )
    missing_tol = [k for k in TOLERANCES if k not in tolerances]
    if missing_tol:
        raise CrossCheckError(
            f"tolerances has no entry for {', '.join(missing_tol)}; expected every quantity of "
            f"TOLERANCES ({', '.join(TOLERANCES)})"
        )
    m, features = comparison_model(robot.mj_model, robot.scene_body_ids)
    notes: list[str] = []
    try:
        check_agreement(robot)
    except ModelMismatchError as exc:
        notes.append(f"load-time agreement check found differences: {exc}")
    pin_file, mj_file = str(robot.source.robot_file), str(robot.source.scene_file)
    problems = structure_problems(robot)
    if problems or robot.nv == 0:
        why = "; ".join(problems) if problems else "the robot has no degrees of freedom"
        return _structure_failure(robot, seed, tolerances, features, notes, why, pin_file, mj_file)
    notes += located_differences(robot)
    frames = match_frames(robot)
    if frames.missing:
        notes.append(
            f"not compared: {len(frames.missing)} MuJoCo frames have no Pinocchio frame of the "
            f"same name and kind (a body: a BODY frame; a site: an OP_FRAME or a link on a fixed joint) "
            f"({_first(frames.missing)})"
        )
    states = sample_states(robot, n_states, seed, sampling)
    t0 = time.perf_counter()
    evaluator = Evaluator(robot, m, frames, chunk_size)
    errors = evaluator.run(states, progress)
    elapsed = time.perf_counter() - t0
    nb = frames.mj_body_ids.size
    frame_labels = [f"body {n!r}" for n in frames.names[:nb]] + [f"site {n!r}" for n in frames.names[nb:]]
    results = [
        QuantityResult(
            "structure",
            "joint order and q/v layout",
            "-",
            0.0,
            0.0,
            0.0,
            0.0,
            -1,
            "-",
            PASS,
            "same joints, same q and v slices in both engines",
        )
    ]
    for name, tol in ((k, tolerances[k]) for k in TOLERANCES):
        if name.startswith(("fk_", "jacobian_")) and not frames.pin_ids:
            results.append(
                QuantityResult(
                    name,
                    tol.description,
                    tol.unit,
                    np.nan,
                    np.nan,
                    tol.rtol,
                    tol.floor,
                    -1,
                    "-",
                    NOT_COMPARED,
                    "no MuJoCo body or site has a Pinocchio frame of its name",
                )
            )
            continue
        err, scale = errors[name]
        worst = int(np.argmax(err))
        abs_err = float(err[worst])
        rel = abs_err / max(float(np.max(scale)), tol.floor)
        status = PASS if rel <= tol.rtol else FAIL
        where = ""
        if status == FAIL:
            index = evaluator.worst_entry(states, worst, name)
            where = describe_entry(name, index, frame_labels, dof_labels(robot))
        results.append(
            QuantityResult(
                name,
                tol.description,
                tol.unit,
                abs_err,
                rel,
                tol.rtol,
                tol.floor,
                worst,
                states.kinds[worst],
                status,
                tol.method,
                worst_entry=where,
            )
        )
    kinds: dict[str, int] = {}
    for k in states.kinds:
        kinds[k] = kinds.get(k, 0) + 1
    return Report(
        robot.name,
        pin_file,
        mj_file,
        len(states.kinds),
        int(seed),
        kinds,
        tuple(results),
        features,
        tuple(notes),
        elapsed,
        robot.source.edits,
    )


def _structure_failure(
    robot: Robot,
    seed: int,
    tolerances: Mapping[str, Tolerance],
    features: tuple[FeatureNote, ...],
    notes: list[str],
    why: str,
    pin_file: str,
    mj_file: str,
) -> Report:
    results = [
        QuantityResult(
            "structure",
            "joint order and q/v layout",
            "-",
            np.inf,
            np.inf,
            0.0,
            0.0,
            -1,
            "-",
            FAIL,
            why,
        )
    ]
    results += [
        QuantityResult(
            k,
            t.description,
            t.unit,
            np.nan,
            np.nan,
            t.rtol,
            t.floor,
            -1,
            "-",
            NOT_COMPARED,
            "the joint layouts differ, states cannot be mapped",
        )
        for k, t in ((k, tolerances[k]) for k in TOLERANCES)
    ]
    return Report(
        robot.name, pin_file, mj_file, 0, int(seed), {}, tuple(results), features, tuple(notes), 0.0,
        robot.source.edits,
    )
