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
from typing import NamedTuple

import mujoco
import numpy as np
import pinocchio as pin

from mbctl.robots.crosscheck.exceptions import CrossCheckError
from mbctl.robots.crosscheck.locate import describe_entry, dof_labels
from mbctl.robots.crosscheck.plant import comparison_model, static_bodies, top_moving_bodies
from mbctl.robots.crosscheck.report import (
    FAIL,
    NOT_COMPARED,
    PASS,
    FeatureNote,
    QuantityResult,
    Report,
)
from mbctl.robots.crosscheck.sampling import Sampling, States, sample_states
from mbctl.robots.crosscheck.structure import first as _first
from mbctl.robots.crosscheck.structure import located_differences, structure_problems
from mbctl.robots.crosscheck.tolerances import TOLERANCES, Tolerance
from mbctl.robots.exceptions import ModelMismatchError
from mbctl.robots.model_pair import Robot, check_agreement


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of (k, 3) arrays (np.cross costs ~40 us per call here)."""
    return np.stack(
        [
            a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1],
            a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
            a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0],
        ],
        axis=1,
    )


class _Frames(NamedTuple):
    pin_ids: list[int]
    mj_body_ids: np.ndarray
    mj_site_ids: np.ndarray
    names: list[str]
    missing: list[str]


def _match_frames(robot: Robot) -> _Frames:
    pm = robot.pin_model
    pin_ids, body_ids, site_ids, names, missing = [], [], [], [], []
    for b, name in zip(robot.robot_body_ids, robot.bodies, strict=True):
        if name and pm.existFrame(name, pin.FrameType.BODY):
            pin_ids.append(pm.getFrameId(name, pin.FrameType.BODY))
            body_ids.append(b)
            names.append(name)
        else:
            missing.append(f"body {name or f'#{b}'}")
    for s, name in zip(robot.robot_site_ids, robot.sites, strict=True):
        if name and pm.existFrame(name, pin.FrameType.OP_FRAME):
            pin_ids.append(pm.getFrameId(name, pin.FrameType.OP_FRAME))
        elif name and pm.existFrame(name):
            pin_ids.append(pm.getFrameId(name))
        else:
            missing.append(f"site {name or f'#{s}'}")
            continue
        site_ids.append(s)
        names.append(name)
    return _Frames(pin_ids, np.array(body_ids, dtype=int), np.array(site_ids, dtype=int), names, missing)


class _Evaluator:
    """Buffers and engine data, allocated once and reused for every state."""

    def __init__(self, robot: Robot, m: mujoco.MjModel, frames: _Frames, chunk: int):
        self.robot, self.m, self.frames, self.chunk = robot, m, frames, chunk
        self.pm = robot.pin_model
        self.pd = self.pm.createData()
        # Kinetic energy like with like: MuJoCo's 1/2 v^T M v has the armature in M, while
        # Pinocchio 4.1's computeKineticEnergy leaves out the armature of revolute joints with an
        # unaligned axis. So Pinocchio's energy of the rigid bodies alone (the same model without
        # armature, on the same data) plus 1/2 v^T diag(armature) v.
        self._pm_rigid = self.pm.copy()
        self._pm_rigid.armature = np.zeros(self.pm.nv)
        self._half_armature = 0.5 * np.asarray(self.pm.armature, dtype=float)
        self.d = mujoco.MjData(m)
        nv, nf = robot.nv, len(frames.pin_ids)
        # The robot's coordinates in the plant; the scene's (a free box) stay at qpos0, at rest.
        self.qi, self.vi = robot.qpos_index, robot.qvel_index
        self.vv = np.ix_(self.vi, self.vi) if isinstance(self.vi, np.ndarray) else (self.vi, self.vi)
        in_robot = set(robot.robot_body_ids)
        self.tops = np.array([b for b in top_moving_bodies(m) if b in in_robot], dtype=int)
        self.top_mass = np.array(m.body_subtreemass[self.tops])
        # Bodies that do not move in the comparison: welded to the world, or scene.
        self.static = np.array(sorted(set(static_bodies(m).tolist()) | set(robot.scene_body_ids)), dtype=int)
        # Per-state outputs of each engine; the frame quantities of Pinocchio live in _H and _J_pin,
        # MuJoCo's Jacobians in _J_mj (mapped through T per chunk).
        shapes = {
            "com": (3,),
            "com_jacobian": (3, nv),
            "mass_matrix": (nv, nv),
            "gravity": (nv,),
            "bias": (nv,),
            "forward_dynamics": (nv,),
            "inverse_dynamics": (nv,),
            "kinetic_energy": (),
            "potential_energy": (),
            "momentum_linear": (3,),
            "momentum_angular": (3,),
        }
        self.pin_out = {k: np.zeros((chunk, *s)) for k, s in shapes.items()}
        self.mj_out = {k: np.zeros((chunk, *s)) for k, s in shapes.items()}
        self.mj_out["fk_position"] = np.zeros((chunk, nf, 3))
        self.mj_out["fk_rotation"] = np.zeros((chunk, nf, 3, 3))
        self._H = np.zeros((chunk, nf, 4, 4))
        self._J_pin = np.zeros((chunk, nf, 6, nv))
        self._J_mj = np.zeros((chunk, nf, 6, m.nv))  # plant columns; the robot's are taken per chunk
        self._T = np.zeros((chunk, nv, nv))
        # Where Pinocchio's matrices with nv columns are written. With nv = 1, eigenpy returns
        # them as vectors ((6,) for a frame Jacobian, (3,) for Jcom), so they go through views
        # without the column axis.
        self._J_pin_out = self._J_pin[..., 0] if nv == 1 else self._J_pin
        self._Jcom_pin_out = self.pin_out["com_jacobian"]
        if nv == 1:
            self._Jcom_pin_out = self._Jcom_pin_out[..., 0]
        # Output views made once: (function, jacp (3, nv), jacr (3, nv), body or site id).
        self._jac_calls = [
            [(mujoco.mj_jacBody, J[k, :3], J[k, 3:], int(b)) for k, b in enumerate(frames.mj_body_ids)]
            + [
                (mujoco.mj_jacSite, J[k, :3], J[k, 3:], int(s))
                for k, s in enumerate(frames.mj_site_ids, start=frames.mj_body_ids.size)
            ]
            for J in self._J_mj
        ]
        self._M_mj = np.zeros((m.nv, m.nv))
        self._jac_com = np.zeros((3, m.nv))
        self._g_mj = np.zeros(m.nv)
        self._pe_static: float | None = None

    def _pin_state(self, i: int, q: np.ndarray, v: np.ndarray, tau: np.ndarray, a: np.ndarray) -> None:
        pm, pd, out = self.pm, self.pd, self.pin_out
        pin.computeAllTerms(pm, pd, q, v)
        pin.updateFramePlacements(pm, pd)
        oMf, H, J = pd.oMf, self._H[i], self._J_pin_out[i]
        lwa = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        for k, f in enumerate(self.frames.pin_ids):
            H[k] = oMf[f].homogeneous
            J[k] = pin.getFrameJacobian(pm, pd, f, lwa)
        out["mass_matrix"][i] = pd.M  # upper triangle; symmetrized per chunk
        out["bias"][i] = pd.nle
        out["gravity"][i] = pd.g
        out["com"][i] = pd.com[0]
        self._Jcom_pin_out[i] = pd.Jcom
        rigid = pin.computeKineticEnergy(self._pm_rigid, pd)  # from pd.v of computeAllTerms
        out["kinetic_energy"][i] = rigid + self._half_armature @ (v * v)
        out["potential_energy"][i] = pd.potential_energy
        hg = pd.hg
        out["momentum_linear"][i] = hg.linear
        out["momentum_angular"][i] = hg.angular
        out["forward_dynamics"][i] = pin.aba(pm, pd, q, v, tau)
        out["inverse_dynamics"][i] = pin.rnea(pm, pd, q, v, a)

    def _mj_state(self, i: int, q: np.ndarray, v: np.ndarray, tau: np.ndarray, a: np.ndarray) -> None:
        m, d, out, conv, fr = self.m, self.d, self.mj_out, self.robot.converter, self.frames
        # The converter's velocity map: v_mj = T v_pin, tau_mj = T tau_pin (T orthogonal),
        # a_mj = T a_pin + Tdot v_pin. Built once per state and applied as matrix products (the
        # converter's per-vector methods would rebuild the rotations for every vector).
        T = conv.velocity_map(q)
        Tdot_v = conv.velocity_map_dot_v(q, v)
        qi, vi = self.qi, self.vi
        d.qpos[qi] = conv.q_pin_to_mj(q)
        d.qvel[vi] = T @ v
        d.qfrc_applied[vi] = T @ tau
        mujoco.mj_forward(m, d)
        nb = fr.mj_body_ids.size
        pos, rot = out["fk_position"][i], out["fk_rotation"][i]
        pos[:nb] = d.xpos[fr.mj_body_ids]
        pos[nb:] = d.site_xpos[fr.mj_site_ids]
        rot[:nb] = d.xmat[fr.mj_body_ids].reshape(-1, 3, 3)
        rot[nb:] = d.site_xmat[fr.mj_site_ids].reshape(-1, 3, 3)
        for jac, jacp, jacr, obj in self._jac_calls[i]:
            jac(m, d, jacp, jacr, obj)
        self._T[i] = T
        mujoco.mj_fullM(m, d, self._M_mj)
        M_mj = self._M_mj[self.vv]  # the robot's block (trees do not couple through M)
        out["mass_matrix"][i] = T.T @ M_mj @ T
        out["bias"][i] = T.T @ (d.qfrc_bias[vi] + M_mj @ Tdot_v)  # the frame change adds M Tdot v
        out["forward_dynamics"][i] = T.T @ (d.qacc[vi] - Tdot_v)
        if self._pe_static is None:  # bodies welded to the world and the scene do not move
            s = self.static
            self._pe_static = float(-np.sum(m.body_mass[s] * (d.xipos[s] @ m.opt.gravity)))
        out["kinetic_energy"][i] = d.energy[1]
        out["potential_energy"][i] = d.energy[0] - self._pe_static
        # Centre of mass and momentum of the moving bodies, from the subtrees that hold them.
        w = self.top_mass / np.sum(self.top_mass)
        p_WC = w @ d.subtree_com[self.tops]
        out["com"][i] = p_WC
        Jc = out["com_jacobian"][i]
        Jc[:] = 0.0
        for r, wr in zip(self.tops, w, strict=True):
            mujoco.mj_jacSubtreeCom(m, d, self._jac_com, r)
            Jc += wr * self._jac_com[:, vi]
        Jc[:] = Jc @ T
        mujoco.mj_subtreeVel(m, d)
        lin = d.subtree_linvel[self.tops] * self.top_mass[:, None]
        out["momentum_linear"][i] = lin.sum(axis=0)
        lever = d.subtree_com[self.tops] - p_WC
        out["momentum_angular"][i] = (d.subtree_angmom[self.tops] + _cross(lever, lin)).sum(axis=0)
        # Inverse dynamics at the same (q, v): the position and velocity stages are current.
        d.qacc[:] = 0.0
        d.qacc[vi] = T @ a + Tdot_v
        mujoco.mj_inverseSkip(m, d, mujoco.mjtStage.mjSTAGE_VEL, 1)
        out["inverse_dynamics"][i] = T.T @ d.qfrc_inverse[vi]
        # Gravity: the bias force at zero velocity (mj_rne reads cvel, so recompute it).
        d.qvel[:] = 0.0
        mujoco.mj_comVel(m, d)
        mujoco.mj_rne(m, d, 0, self._g_mj)
        out["gravity"][i] = T.T @ self._g_mj[vi]

    def _evaluate(self, states: States, start: int, stop: int) -> None:
        """Evaluate states ``start:stop`` (at most ``chunk``) into buffer slots 0 .. stop - start."""
        for i, s in enumerate(range(start, stop)):
            args = (i, states.q[s], states.v[s], states.tau[s], states.a[s])
            self._pin_state(*args)
            self._mj_state(*args)

    def _aligned(self, c: int) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
        """Pinocchio's and MuJoCo's values of the first ``c`` slots, in the same convention.

        The frame Jacobians are under "jacobian", all 6 rows (c, nf, 6, nv); every other
        quantity under its name in ``TOLERANCES``.
        """
        P, Q = {k: v[:c] for k, v in self.pin_out.items()}, {k: v[:c] for k, v in self.mj_out.items()}
        H, Jp = self._H[:c], self._J_pin[:c]
        P["fk_position"], P["fk_rotation"] = H[:, :, :3, 3], H[:, :, :3, :3]
        M = np.triu(P["mass_matrix"])  # crba fills the upper triangle
        P["mass_matrix"] = M + np.triu(M, 1).swapaxes(-1, -2)
        # J_mj v_mj = J_mj T v_pin, so J_pin = J_mj T (one batched product per chunk).
        Jm = self._J_mj[:c][..., self.vi]
        Jm = np.matmul(Jm.reshape(c, -1, Jm.shape[-1]), self._T[:c]).reshape(Jm.shape)
        P["jacobian"], Q["jacobian"] = Jp, Jm
        return P, Q

    def run(
        self, states: States, progress: Callable[[int, int], None] | None = None
    ) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Per quantity: (abs error per state (n,), MuJoCo magnitude per state (n,)).

        ``progress(done, n)`` is called after each chunk, if given.
        """
        n = len(states.kinds)
        errors = {k: (np.zeros(n), np.zeros(n)) for k in TOLERANCES}
        for start in range(0, n, self.chunk):
            stop = min(start + self.chunk, n)
            self._evaluate(states, start, stop)
            P, Q = self._aligned(stop - start)
            # Full 6-row differences once; linear and angular rows are reduced from them.
            Jp, Jm = P["jacobian"], Q["jacobian"]
            J_diff, J_mag = np.abs(Jp - Jm), np.abs(Jm)
            reduced = {
                "jacobian_linear": (J_diff[:, :, :3], J_mag[:, :, :3]),
                "jacobian_angular": (J_diff[:, :, 3:], J_mag[:, :, 3:]),
            }
            for k, (err, scale) in errors.items():
                if k in reduced:
                    diff, mag = reduced[k]
                else:
                    diff, mag = np.abs(P[k] - Q[k]), np.abs(Q[k])
                if diff.size == 0:
                    continue
                axes = tuple(range(1, diff.ndim))
                worst = diff.max(axis=axes) if axes else diff  # NaN propagates through max
                err[start:stop] = np.where(np.isnan(worst), np.inf, worst)
                scale[start:stop] = mag.max(axis=axes) if axes else mag
            if progress is not None:
                progress(stop, n)
        return errors

    def worst_entry(self, states: States, s: int, quantity: str) -> tuple[int, ...]:
        """Index of the largest error of ``quantity`` within state ``s`` (first NaN if any).

        Evaluates state ``s`` again (into slot 0), so it costs one state; called for failing
        quantities only.
        """
        self._evaluate(states, s, s + 1)
        P, Q = self._aligned(1)
        rows = {"jacobian_linear": slice(0, 3), "jacobian_angular": slice(3, 6)}
        if quantity in rows:
            diff = np.abs(P["jacobian"][0] - Q["jacobian"][0])[:, rows[quantity]]
        else:
            diff = np.abs(P[quantity][0] - Q[quantity][0])
        if diff.ndim == 0:
            return ()
        flat = int(np.argmax(diff))  # NaN counts as the maximum
        return tuple(int(i) for i in np.unravel_index(flat, diff.shape))


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
    chunk_size: int = 16,
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
        chunk_size: States evaluated between two vectorized error reductions; 16 keeps the
            buffers of a G1-sized robot (~85 kB of Jacobians per state and engine) in cache.
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
    frames = _match_frames(robot)
    if frames.missing:
        notes.append(
            f"not compared: {len(frames.missing)} MuJoCo frames have no Pinocchio frame of the "
            f"same name ({_first(frames.missing)})"
        )
    states = sample_states(robot, n_states, seed, sampling)
    t0 = time.perf_counter()
    evaluator = _Evaluator(robot, m, frames, chunk_size)
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
