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
* kinetic and potential energy; centroidal momentum against MuJoCo's subtree momentum.

MuJoCo runs on a private copy of the plant with everything outside rigid-body dynamics switched
off (see ``crosscheck_plant``); the report says what that was and what could not be compared.

Errors: for a quantity with Pinocchio values ``a_s`` and MuJoCo values ``b_s`` over states s,
``abs = max_s max_i |a_si - b_si|`` and ``rel = abs / max(max_s max_i |b_si|, floor)``. The
denominator is the quantity's magnitude over the whole run, not per state, so a state where a
quantity is small by cancellation (a potential energy near zero) does not inflate the error; the
floor only binds when the quantity is (nearly) zero in every state (gravity with gravity off).
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import NamedTuple

import mujoco
import numpy as np
import pinocchio as pin

from mbctl.robots.crosscheck.plant import comparison_model, static_bodies, top_moving_bodies
from mbctl.robots.crosscheck.report import (
    FAIL,
    NOT_COMPARED,
    PASS,
    FeatureNote,
    QuantityResult,
    Report,
)
from mbctl.robots.exceptions import ModelMismatchError, RobotError
from mbctl.robots.model_pair import Robot, check_agreement


class CrossCheckError(RobotError):
    """Invalid cross-check arguments (number of states, seed, tolerances)."""


@dataclass(frozen=True)
class Tolerance:
    """Pass criterion of one quantity: ``rel = abs / max(scale, floor) <= rtol``.

    Attributes:
        rtol: Largest passing relative error [-].
        floor: Magnitude [unit] below which the quantity counts as zero.
        unit: SI unit of the quantity.
        description: What is compared, with the frame.
    """

    rtol: float
    floor: float
    unit: str
    description: str

    def __post_init__(self) -> None:
        """Reject non-positive or non-finite tolerances."""
        for name in ("rtol", "floor"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise CrossCheckError(f"Tolerance.{name} must be a positive finite number; got {value!r}")


#: Relative tolerance of every quantity [-]. Both engines evaluate the same closed-form rigid-body
#: expressions in double precision; measured agreement is 1e-16 .. 1e-13 relative (the G1 and
#: the 2-link arm, see the tests). 1e-9 leaves a margin of 1e4 for round-off growth (forward
#: dynamics loses ~cond(M) * eps; a mass matrix with cond(M) = 1e6 still passes), while any
#: physical modelling difference worth having (a 1e-6 relative change of a mass, a 1 um shift
#: of an inertial frame) still fails.
RTOL = 1e-9

#: The floors are magnitudes below which a quantity is "zero" for a robot of any size we support
#: (a 0.1 kg finger to a 100 kg humanoid). They matter only when a quantity vanishes in every
#: state (gravity and potential energy with gravity off, the Jacobians of a body welded to the
#: world); then ``rel = abs / floor`` and the absolute error must stay below ``RTOL * floor``,
#: e.g. 1e-12 N m for gravity torques, still 1e3 above round-off of a zero quantity.
TOLERANCES: Mapping[str, Tolerance] = MappingProxyType(
    {
        # Rotation matrices have entries of magnitude 1 (every row has unit norm): floor 1.
        "fk_position": Tolerance(RTOL, 1e-3, "m", "p_WF of every body and site, world frame"),
        "fk_rotation": Tolerance(RTOL, 1.0, "-", "R_WF of every body and site"),
        "jacobian_linear": Tolerance(
            RTOL, 1e-3, "m/rad", "J_WF linear rows, LOCAL_WORLD_ALIGNED, every body and site"
        ),
        "jacobian_angular": Tolerance(
            RTOL, 1.0, "-", "J_WF angular rows, LOCAL_WORLD_ALIGNED, every body and site"
        ),
        "com": Tolerance(RTOL, 1e-3, "m", "p_WC, centre of mass of the moving bodies, world frame"),
        "com_jacobian": Tolerance(RTOL, 1e-3, "m/rad", "J_WC, world frame"),
        # 1e-6 kg m^2: inertia of a 10 g, 1 cm body; armatures are larger.
        "mass_matrix": Tolerance(RTOL, 1e-6, "kg m^2", "M(q) with armature"),
        "gravity": Tolerance(RTOL, 1e-3, "N m", "g(q), generalized gravity force"),
        "bias": Tolerance(RTOL, 1e-3, "N m", "b(q, v) = C(q, v) v + g(q)"),
        "forward_dynamics": Tolerance(RTOL, 1e-3, "rad/s^2", "a = FD(q, v, tau): ABA vs qacc"),
        "inverse_dynamics": Tolerance(RTOL, 1e-3, "N m", "tau = ID(q, v, a): RNEA vs mj_inverse"),
        "kinetic_energy": Tolerance(RTOL, 1e-6, "J", "kinetic energy 0.5 v^T M v (armature included)"),
        "potential_energy": Tolerance(RTOL, 1e-6, "J", "gravitational energy of the moving bodies"),
        "momentum_linear": Tolerance(RTOL, 1e-6, "kg m/s", "centroidal linear momentum, world axes"),
        "momentum_angular": Tolerance(
            RTOL, 1e-6, "kg m^2/s", "centroidal angular momentum about the CoM, world axes"
        ),
    }
)


@dataclass(frozen=True)
class Sampling:
    """How random states are drawn.

    Limited hinge and slide joints are uniform within their MuJoCo ``range``; unlimited hinges
    uniform in [-pi, pi]; free and ball joints get a uniform random unit quaternion.

    Attributes:
        position_range_m: Free-joint positions uniform in [-r, r]^3 [m]; unlimited slides too.
        velocity_std: Standard deviation of each velocity coordinate [rad/s] or [m/s].
        torque_std: Standard deviation of each generalized force [N m] or [N].
        acceleration_std: Standard deviation of each acceleration for inverse dynamics
            [rad/s^2] or [m/s^2].
    """

    position_range_m: float = 1.0
    velocity_std: float = 1.0
    torque_std: float = 10.0
    acceleration_std: float = 10.0


class States(NamedTuple):
    """States of a cross-check, in Pinocchio's convention.

    Attributes:
        q: Configurations (n, nq).
        v: Velocities (n, nv).
        tau: Generalized forces for forward dynamics (n, nv) [N m] or [N].
        a: Accelerations for inverse dynamics (n, nv) [rad/s^2] or [m/s^2].
        kinds: Kind of each state ("random", "zero velocity", ...), length n.
    """

    q: np.ndarray
    v: np.ndarray
    tau: np.ndarray
    a: np.ndarray
    kinds: tuple[str, ...]


def sample_states(robot: Robot, n_states: int, seed: int, sampling: Sampling = Sampling()) -> States:
    """``n_states`` random states plus edge states, reproducible from ``seed``.

    Edge states (placed first): neutral configuration at zero velocity; a random configuration
    at zero velocity; and, if the robot has limited joints, all limited hinges and slides at their
    lower limits, then at their upper limits (other joints random, velocity random).

    Args:
        robot: The model pair; limits come from the MuJoCo model (the plant).
        n_states: Number of random states (>= 0).
        seed: Seed of ``numpy.random.default_rng``.
        sampling: Ranges and scales of the random draws.

    Returns:
        The states, in Pinocchio's convention.
    """
    m = robot.mj_model
    rng = np.random.default_rng(seed)
    jids = {name: i for i, name in enumerate(robot.joints)}
    limited = [
        (j.idx_q, jids[j.name])
        for j in robot.joints.values()
        if j.kind in ("hinge", "slide") and m.jnt_limited[jids[j.name]]
    ]
    kinds = ["neutral, v = 0", "zero velocity"]
    if limited:
        kinds += ["lower limits", "upper limits"]
    kinds += ["random"] * n_states
    n, r = len(kinds), sampling.position_range_m
    q = np.tile(robot.neutral_q(), (n, 1))
    for j in robot.joints.values():  # one draw per joint for all states at once
        at = j.idx_q
        if j.kind in ("free", "ball"):
            if j.kind == "free":
                q[:, at : at + 3] = rng.uniform(-r, r, (n, 3))
                at += 3
            quat_xyzw = rng.normal(size=(n, 4))  # isotropic Gaussian -> uniform on S^3
            q[:, at : at + 4] = quat_xyzw / np.linalg.norm(quat_xyzw, axis=1, keepdims=True)
        elif m.jnt_limited[jids[j.name]]:
            lo, hi = m.jnt_range[jids[j.name]]
            q[:, at] = rng.uniform(lo, hi, n)
        elif j.kind == "hinge":
            q[:, at] = rng.uniform(-np.pi, np.pi, n)
        else:
            q[:, at] = rng.uniform(-r, r, n)
    q[0] = robot.neutral_q()
    for iq, jid in limited:
        q[2, iq], q[3, iq] = m.jnt_range[jid]
    v = rng.normal(0, sampling.velocity_std, (n, robot.nv))
    v[:2] = 0.0
    tau = rng.normal(0, sampling.torque_std, (n, robot.nv))
    a = rng.normal(0, sampling.acceleration_std, (n, robot.nv))
    return States(q, v, tau, a, tuple(kinds))


def _structure_problems(robot: Robot) -> list[str]:
    pm, m = robot.pin_model, robot.mj_model
    problems = []
    if (pm.nq, pm.nv) != (m.nq, m.nv):
        problems.append(f"sizes differ: Pinocchio nq={pm.nq}, nv={pm.nv}; MuJoCo nq={m.nq}, nv={m.nv}")
    if pm.njoints - 1 != len(robot.joints):
        problems.append(f"joint count differs: Pinocchio {pm.njoints - 1}, MuJoCo {len(robot.joints)}")
        top_level = int(np.count_nonzero(m.body_parentid[1:] == 0))
        if pm.njoints - 1 < len(robot.joints) and top_level > 1:
            problems.append(
                f"the MuJoCo model has {top_level} bodies directly under <worldbody>, and Pinocchio "
                "4.1's MJCF parser builds only the first body tree: put the robot first, or give the "
                "Pinocchio side its own file (--pin-model / pin_model_file)"
            )
    else:
        for k, j in enumerate(robot.joints.values(), start=1):
            pj = pm.joints[k]
            if (pj.idx_q, pj.idx_v, pj.nq, pj.nv) != (j.idx_q, j.idx_v, j.nq, j.nv):
                problems.append(
                    f"joint #{k - 1} ({j.name!r}, MuJoCo {j.kind}) has q[{j.idx_q}:+{j.nq}] "
                    f"v[{j.idx_v}:+{j.nv}] in MuJoCo but q[{pj.idx_q}:+{pj.nq}] "
                    f"v[{pj.idx_v}:+{pj.nv}] in Pinocchio ({pm.names[k]!r}, {pj.shortname()})"
                )
                break
    return problems


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


def _known_pinocchio_discrepancies(robot: Robot) -> list[str]:
    """Notes on Pinocchio behaviour this check has found to differ, so a failure names its cause."""
    pm = robot.pin_model
    unaligned = [
        pm.names[k]
        for k in range(1, pm.njoints)
        if pm.joints[k].shortname() == "JointModelRevoluteUnaligned"
        and float(pm.armature[pm.joints[k].idx_v]) != 0.0
    ]
    if not unaligned:
        return []
    return [
        "known Pinocchio 4.1 discrepancy: computeKineticEnergy leaves out the armature of revolute "
        "joints with a non-axis-aligned axis (crba includes it), so kinetic_energy differs by "
        f"0.5 armature v^2 on: {', '.join(unaligned[:6])}"
    ]


class _Frames(NamedTuple):
    pin_ids: list[int]
    mj_body_ids: np.ndarray
    mj_site_ids: np.ndarray
    names: list[str]
    missing: list[str]


def _match_frames(robot: Robot) -> _Frames:
    pm = robot.pin_model
    pin_ids, body_ids, site_ids, names, missing = [], [], [], [], []
    for b, name in enumerate(robot.bodies, start=1):
        if name and pm.existFrame(name, pin.FrameType.BODY):
            pin_ids.append(pm.getFrameId(name, pin.FrameType.BODY))
            body_ids.append(b)
            names.append(name)
        else:
            missing.append(f"body {name or f'#{b}'}")
    for s, name in enumerate(robot.sites):
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
        self.d = mujoco.MjData(m)
        nv, nf = m.nv, len(frames.pin_ids)
        self.tops = top_moving_bodies(m)
        self.top_mass = np.array(m.body_subtreemass[self.tops])
        self.static = static_bodies(m)
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
        self._J_mj = np.zeros((chunk, nf, 6, nv))
        self._T = np.zeros((chunk, nv, nv))
        # Output views made once: (function, jacp (3, nv), jacr (3, nv), body or site id).
        self._jac_calls = [
            [(mujoco.mj_jacBody, J[k, :3], J[k, 3:], int(b)) for k, b in enumerate(frames.mj_body_ids)]
            + [
                (mujoco.mj_jacSite, J[k, :3], J[k, 3:], int(s))
                for k, s in enumerate(frames.mj_site_ids, start=frames.mj_body_ids.size)
            ]
            for J in self._J_mj
        ]
        self._M_mj = np.zeros((nv, nv))
        self._jac_com = np.zeros((3, nv))
        self._g_mj = np.zeros(nv)
        self._pe_static: float | None = None

    def _pin_state(self, i: int, q: np.ndarray, v: np.ndarray, tau: np.ndarray, a: np.ndarray) -> None:
        pm, pd, out = self.pm, self.pd, self.pin_out
        pin.computeAllTerms(pm, pd, q, v)
        pin.updateFramePlacements(pm, pd)
        oMf, H, J = pd.oMf, self._H[i], self._J_pin[i]
        lwa = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        for k, f in enumerate(self.frames.pin_ids):
            H[k] = oMf[f].homogeneous
            J[k] = pin.getFrameJacobian(pm, pd, f, lwa)
        out["mass_matrix"][i] = pd.M  # upper triangle; symmetrized per chunk
        out["bias"][i] = pd.nle
        out["gravity"][i] = pd.g
        out["com"][i] = pd.com[0]
        out["com_jacobian"][i] = pd.Jcom
        out["kinetic_energy"][i] = pd.kinetic_energy
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
        d.qpos[:] = conv.q_pin_to_mj(q)
        d.qvel[:] = T @ v
        d.qfrc_applied[:] = T @ tau
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
        M_mj = self._M_mj
        out["mass_matrix"][i] = T.T @ M_mj @ T
        out["bias"][i] = T.T @ (d.qfrc_bias + M_mj @ Tdot_v)  # the frame change adds M Tdot v
        out["forward_dynamics"][i] = T.T @ (d.qacc - Tdot_v)
        if self._pe_static is None:  # bodies welded to the world do not move
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
            Jc += wr * self._jac_com
        Jc[:] = Jc @ T
        mujoco.mj_subtreeVel(m, d)
        lin = d.subtree_linvel[self.tops] * self.top_mass[:, None]
        out["momentum_linear"][i] = lin.sum(axis=0)
        lever = d.subtree_com[self.tops] - p_WC
        out["momentum_angular"][i] = (d.subtree_angmom[self.tops] + _cross(lever, lin)).sum(axis=0)
        # Inverse dynamics at the same (q, v): the position and velocity stages are current.
        d.qacc[:] = T @ a + Tdot_v
        mujoco.mj_inverseSkip(m, d, mujoco.mjtStage.mjSTAGE_VEL, 1)
        out["inverse_dynamics"][i] = T.T @ d.qfrc_inverse
        # Gravity: the bias force at zero velocity (mj_rne reads cvel, so recompute it).
        d.qvel[:] = 0.0
        mujoco.mj_comVel(m, d)
        mujoco.mj_rne(m, d, 0, self._g_mj)
        out["gravity"][i] = T.T @ self._g_mj

    def run(self, states: States) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Per quantity: (abs error per state (n,), MuJoCo magnitude per state (n,))."""
        n = len(states.kinds)
        errors = {k: (np.zeros(n), np.zeros(n)) for k in TOLERANCES}
        for start in range(0, n, self.chunk):
            stop = min(start + self.chunk, n)
            for i, s in enumerate(range(start, stop)):
                args = (i, states.q[s], states.v[s], states.tau[s], states.a[s])
                self._pin_state(*args)
                self._mj_state(*args)
            c = stop - start
            P, Q = {k: v[:c] for k, v in self.pin_out.items()}, {k: v[:c] for k, v in self.mj_out.items()}
            H, Jp = self._H[:c], self._J_pin[:c]
            P["fk_position"], P["fk_rotation"] = H[:, :, :3, 3], H[:, :, :3, :3]
            M = np.triu(P["mass_matrix"])  # crba fills the upper triangle
            P["mass_matrix"] = M + np.triu(M, 1).swapaxes(-1, -2)
            # J_mj v_mj = J_mj T v_pin, so J_pin = J_mj T (one batched product per chunk).
            Jm = self._J_mj[:c]
            Jm = np.matmul(Jm.reshape(c, -1, self.m.nv), self._T[:c]).reshape(Jm.shape)
            # Full 6-row differences once; linear and angular rows are reduced from them.
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
        return errors


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
    sampling: Sampling = Sampling(),
    chunk_size: int = 16,
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

    Returns:
        The report: per quantity max abs and relative error, tolerance, worst state and status;
        the model features left out and why; notes (load-time agreement check, unmatched frames).

    Raises:
        CrossCheckError: ``n_states`` or ``seed`` not a non-negative integer, ``chunk_size`` < 1,
            or ``tolerances`` missing a quantity.
    """
    _validate(n_states, seed)
    if isinstance(chunk_size, bool) or not isinstance(chunk_size, (int, np.integer)) or chunk_size < 1:
        raise CrossCheckError(f"chunk_size must be an integer >= 1; got {chunk_size!r}")
    missing_tol = [k for k in TOLERANCES if k not in tolerances]
    if missing_tol:
        raise CrossCheckError(
            f"tolerances has no entry for {', '.join(missing_tol)}; expected every quantity of "
            f"TOLERANCES ({', '.join(TOLERANCES)})"
        )
    m, features = comparison_model(robot.mj_model)
    notes: list[str] = []
    try:
        check_agreement(robot)
    except ModelMismatchError as exc:
        notes.append(f"load-time agreement check found differences: {exc}")
    pin_file, mj_file = str(robot.source.robot_file), str(robot.source.scene_file)
    problems = _structure_problems(robot)
    if problems or robot.nv == 0:
        why = "; ".join(problems) if problems else "the robot has no degrees of freedom"
        return _structure_failure(robot, seed, tolerances, features, notes, why, pin_file, mj_file)
    notes += _known_pinocchio_discrepancies(robot)
    frames = _match_frames(robot)
    if frames.missing:
        shown = ", ".join(frames.missing[:8]) + (
            f" and {len(frames.missing) - 8} more" if len(frames.missing) > 8 else ""
        )
        notes.append(
            f"not compared: {len(frames.missing)} MuJoCo frames have no Pinocchio frame of the "
            f"same name ({shown})"
        )
    states = sample_states(robot, n_states, seed, sampling)
    t0 = time.perf_counter()
    errors = _Evaluator(robot, m, frames, chunk_size).run(states)
    elapsed = time.perf_counter() - t0
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
        robot.name, pin_file, mj_file, 0, int(seed), {}, tuple(results), features, tuple(notes), 0.0
    )
