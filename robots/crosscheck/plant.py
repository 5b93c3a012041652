"""The MuJoCo side of a cross-check: a private copy of the plant reduced to rigid-body dynamics.

MuJoCo simulates more than the rigid-body equations ``M(q) a + b(q, v) = tau`` that Pinocchio
evaluates: contacts, joint and tendon limits, equality constraints, dry friction, damping,
springs, gravity compensation, fluid forces and actuators. ``comparison_model`` switches these
off on a copy of the MjModel (the caller's model is untouched) and says, feature by feature, what
the plant has and how it was handled:

* "excluded": switched off; the remaining rigid-body comparison is still a fair comparison of
  the two models, and the feature is simply outside it (e.g. contact, frictionloss, damping).
* "accounted": corrected for explicitly (potential energy of static bodies with mass).
* "not compared": the plant's motion depends on something the Pinocchio model cannot express
  (binding equality constraints, force-producing tendons, gravity compensation, flexes). The
  rigid-body quantities are still compared, but the report must not read as a clean pass.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence

import mujoco
import numpy as np

from mbctl.robots.crosscheck.report import ACCOUNTED, EXCLUDED, NOT_COMPARED, FeatureNote
from mbctl.robots.scene import describe_body

_D = mujoco.mjtDisableBit

#: Disable flags set on the private copy, each with the feature it removes.
DISABLE_FLAGS = (
    (_D.mjDSBL_CONTACT, "contact"),
    (_D.mjDSBL_LIMIT, "joint and tendon limits"),
    (_D.mjDSBL_EQUALITY, "equality constraints"),
    (_D.mjDSBL_FRICTIONLOSS, "frictionloss"),
    (_D.mjDSBL_SPRING, "springs"),
    (_D.mjDSBL_DAMPER, "damping"),
    (_D.mjDSBL_ACTUATION, "actuators"),
)


def _count_and_max(values: np.ndarray) -> tuple[int, float]:
    nonzero = np.abs(values) > 0
    return int(np.count_nonzero(nonzero)), float(np.max(np.abs(values))) if values.size else 0.0


def _names(m: mujoco.MjModel, objtype: mujoco.mjtObj, ids: np.ndarray, limit: int = 6) -> str:
    names = [mujoco.mj_id2name(m, objtype, int(i)) or f"#{int(i)}" for i in ids[:limit]]
    more = f" and {ids.size - limit} more" if ids.size > limit else ""
    return ", ".join(names) + more


def static_bodies(m: mujoco.MjModel) -> np.ndarray:
    """Ids of bodies (world excluded) welded to the world, i.e. with no joint above them."""
    return np.flatnonzero(m.body_weldid[1:] == 0) + 1


def top_moving_bodies(m: mujoco.MjModel) -> np.ndarray:
    """Ids of moving bodies whose parent is static: their subtrees are all the moving mass."""
    moving = m.body_weldid != 0
    return np.array([b for b in range(1, m.nbody) if moving[b] and not moving[m.body_parentid[b]]], dtype=int)


def audit(m: mujoco.MjModel, scene: Sequence[int] = ()) -> tuple[FeatureNote, ...]:
    """What ``m`` simulates beyond rigid-body dynamics, and how the cross-check handles each.

    ``scene`` holds the ids of the plant's bodies that are not the robot.
    """
    notes: list[FeatureNote] = []
    if len(scene):
        ids = np.asarray(scene, dtype=int)
        described = ", ".join(describe_body(m, int(b)) for b in ids[:6])
        notes.append(
            FeatureNote(
                "scene bodies",
                EXCLUDED,
                f"{ids.size} bodies are scene, not robot ({described}"
                f"{f' and {ids.size - 6} more' if ids.size > 6 else ''}); they stay at rest at their qpos0 "
                "pose and only the robot's coordinates are compared.",
            )
        )
    collidable = np.flatnonzero((m.geom_contype != 0) | (m.geom_conaffinity != 0))
    if collidable.size or m.npair:
        notes.append(
            FeatureNote(
                "contact",
                EXCLUDED,
                f"{collidable.size} geoms with contype/conaffinity and {m.npair} explicit contact "
                "pairs; contact forces need a contact model that Pinocchio's rigid-body algorithms "
                "do not have (mjDSBL_CONTACT).",
            )
        )
    limited = np.flatnonzero(m.jnt_limited)
    if limited.size:
        notes.append(
            FeatureNote(
                "joint limits",
                EXCLUDED,
                f"{limited.size} limited joints ({_names(m, mujoco.mjtObj.mjOBJ_JOINT, limited)}); "
                "limits are constraint forces in MuJoCo only (mjDSBL_LIMIT). The limits were "
                "used to sample states, including states at the limits.",
            )
        )
    if m.neq:
        active = np.flatnonzero(m.eq_active0)
        if active.size:
            notes.append(
                FeatureNote(
                    "equality constraints",
                    NOT_COMPARED,
                    f"{active.size} of {m.neq} equality constraints are active "
                    f"({_names(m, mujoco.mjtObj.mjOBJ_EQUALITY, active)}); they bind the plant's "
                    "motion and the Pinocchio model has no constraint for them, so the constrained "
                    "dynamics are not compared (mjDSBL_EQUALITY for the rigid-body part).",
                )
            )
        else:
            notes.append(
                FeatureNote(
                    "equality constraints",
                    EXCLUDED,
                    f"{m.neq} equality constraints, none active at start (mjDSBL_EQUALITY).",
                )
            )
    n, biggest = _count_and_max(m.dof_frictionloss)
    if n:
        notes.append(
            FeatureNote(
                "frictionloss",
                EXCLUDED,
                f"{n} dofs with dry friction up to {biggest:g} N m (or N); MuJoCo models it as a "
                "constraint force, the Pinocchio model has none (mjDSBL_FRICTIONLOSS).",
            )
        )
    n, biggest = _count_and_max(m.dof_damping)
    if n:
        notes.append(
            FeatureNote(
                "damping",
                EXCLUDED,
                f"{n} dofs with viscous damping up to {biggest:g} N m s/rad (or N s/m); a passive "
                "force outside M a + b (mjDSBL_DAMPER).",
            )
        )
    n, biggest = _count_and_max(m.jnt_stiffness)
    if n:
        notes.append(
            FeatureNote(
                "springs",
                EXCLUDED,
                f"{n} joints with stiffness up to {biggest:g} N m/rad (or N/m); a passive force "
                "outside M a + b, and its energy is left out of MuJoCo's potential energy "
                "(mjDSBL_SPRING).",
            )
        )
    if m.nu:
        notes.append(
            FeatureNote(
                "actuators",
                EXCLUDED,
                f"{m.nu} actuators; generalized forces are applied directly (qfrc_applied), so "
                "actuator gains, bias terms and activation dynamics are not part of the comparison "
                "(mjDSBL_ACTUATION).",
            )
        )
    gravcomp = np.flatnonzero(m.body_gravcomp)
    if gravcomp.size:
        names = _names(m, mujoco.mjtObj.mjOBJ_BODY, gravcomp)
        notes.append(
            FeatureNote(
                "gravity compensation",
                NOT_COMPARED,
                f"{gravcomp.size} bodies with gravcomp ({names}); MuJoCo cancels part of their "
                "weight, Pinocchio's g(q) does not. Set to zero in the comparison copy.",
            )
        )
    if m.ntendon:
        tendon_actuated = np.zeros(m.ntendon, dtype=bool)
        for i in range(m.nu):
            if m.actuator_trntype[i] == mujoco.mjtTrn.mjTRN_TENDON:
                tendon_actuated[m.actuator_trnid[i, 0]] = True
        tendon_eq = np.zeros(m.ntendon, dtype=bool)
        for i in range(m.neq):
            if m.eq_type[i] == mujoco.mjtEq.mjEQ_TENDON:
                tendon_eq[m.eq_obj1id[i]] = True
                if m.eq_obj2id[i] >= 0:
                    tendon_eq[m.eq_obj2id[i]] = True
        forceful = np.flatnonzero(
            (m.tendon_limited != 0)
            | (m.tendon_stiffness != 0)
            | (m.tendon_damping != 0)
            | (m.tendon_frictionloss != 0)
            | tendon_actuated
            | tendon_eq
        )
        if forceful.size:
            names = _names(m, mujoco.mjtObj.mjOBJ_TENDON, forceful)
            notes.append(
                FeatureNote(
                    "tendons",
                    NOT_COMPARED,
                    f"{forceful.size} of {m.ntendon} tendons exert forces (limits, springs, "
                    f"damping, friction, actuators or equality couplings: {names}); Pinocchio "
                    "has no tendons.",
                )
            )
        else:
            notes.append(
                FeatureNote(
                    "tendons",
                    EXCLUDED,
                    f"{m.ntendon} tendons, none exerting force (no limit, spring, damping, "
                    "friction, actuator or equality): they do not change the dynamics.",
                )
            )
    if m.opt.density > 0 or m.opt.viscosity > 0:
        notes.append(
            FeatureNote(
                "fluid forces",
                EXCLUDED,
                f"medium density {m.opt.density:g} kg/m^3, viscosity {m.opt.viscosity:g} Pa s; "
                "environment forces, set to zero in the comparison copy.",
            )
        )
    if m.nflex:
        notes.append(
            FeatureNote(
                "flexes",
                NOT_COMPARED,
                f"{m.nflex} deformable flexes; Pinocchio has rigid bodies only.",
            )
        )
    static = np.union1d(static_bodies(m), np.asarray(scene, dtype=int))
    heavy = static[m.body_mass[static] > 0]
    if heavy.size and np.any(m.opt.gravity != 0):
        notes.append(
            FeatureNote(
                "static bodies with mass",
                ACCOUNTED,
                f"{heavy.size} bodies welded to the world or held still as scene carry "
                f"{np.sum(m.body_mass[heavy]):g} kg ({_names(m, mujoco.mjtObj.mjOBJ_BODY, heavy)}); "
                "MuJoCo's potential energy includes them, the robot's Pinocchio model does not, so "
                "their constant share is subtracted.",
            )
        )
    if m.opt.disableflags & _D.mjDSBL_GRAVITY:
        notes.append(
            FeatureNote(
                "gravity disabled in the plant",
                EXCLUDED,
                "the MuJoCo model disables gravity (mjDSBL_GRAVITY) while Pinocchio uses "
                f"opt.gravity {tuple(m.opt.gravity)}; left as is, so the gravity terms show the "
                "difference.",
            )
        )
    return tuple(notes)


def comparison_model(
    m: mujoco.MjModel, scene: Sequence[int] = ()
) -> tuple[mujoco.MjModel, tuple[FeatureNote, ...]]:
    """A private copy of ``m`` reduced to rigid-body dynamics, and the audit of what was removed.

    On the copy: the flags in ``DISABLE_FLAGS`` are set, energy computation is enabled
    (mjENBL_ENERGY), gravity compensation and fluid forces are zeroed. The plant's own disable
    flags stay as they are.

    Args:
        m: The plant model; not modified.
        scene: Ids of the plant's bodies that are not the robot (for the notes).

    Returns:
        (model copy, feature notes).
    """
    notes = audit(m, scene)
    mc = copy.copy(m)  # MjModel.__copy__ is a deep copy (mj_copyModel)
    for flag, _ in DISABLE_FLAGS:
        mc.opt.disableflags |= int(flag)
    mc.opt.enableflags |= int(mujoco.mjtEnableBit.mjENBL_ENERGY)
    mc.body_gravcomp[:] = 0.0
    mc.opt.density = 0.0
    mc.opt.viscosity = 0.0
    return mc, notes
