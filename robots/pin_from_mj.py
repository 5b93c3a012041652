"""Build the Pinocchio model from MuJoCo's compiled ``MjModel`` instead of parsing the MJCF twice.

Why: Pinocchio's MJCF parser (``pin.buildModelFromMJCF``) re-reads the XML and misses what
MuJoCo's compiler resolves. It drops the pose of a jointless root body (a rotated ``<body>``
without joints under ``<worldbody>`` moves the whole arm), ignores site attributes set by
default classes, drops sites inside ``<frame>``, merges several joints of one body into one
composite joint, reads only the first body tree, does not follow ``<include>`` and computes mesh
inertias differently. The compiled ``MjModel`` has all of that resolved: body poses relative to
the parent, principal inertias, joint axes and anchors in the body frame, site poses in the body
frame. This module copies them into a ``pin.Model``, one body and one joint at a time.

Notation (Drake monograms): ``X_AB`` is the pose of frame B in frame A (``pin.SE3``). ``W`` is the
world, ``P`` a parent body, ``B`` a body, ``J`` a Pinocchio joint frame, ``S`` a site.

The mapping, per MuJoCo body B with parent P (body ids are in depth-first order, so parents come
first and Pinocchio joints are added in MuJoCo's joint order):

* ``X_PB`` from ``body_pos`` and ``body_quat`` (w, x, y, z).
* MuJoCo rotates a hinge or ball joint about its anchor ``jnt_pos`` (in the body frame, after the
  body's earlier joints): ``X_PB(q) = X_PB T(p_1) R_1(q_1) T(-p_1) T(p_2) R_2(q_2) T(-p_2) ...``.
  Pinocchio rotates about its joint frame's origin, so joint k sits at
  ``X_J(k-1),Jk = T(-p_(k-1)) T(p_k)`` (the first at ``X_JP X_PB T(p_1)``), and the body frame,
  its inertia, its sites and any child bodies hang from the last joint at ``T(-p_last)``. Joints
  before the last carry no mass (massless intermediate joint frames). Slide joints use no anchor.
* A free joint sets the body's world pose directly (MuJoCo ignores ``body_pos`` then), so its
  free-flyer sits at the identity in the world. Pinocchio's free-flyer q is (x, y, z, qx, qy, qz,
  qw) and its v is base-local; MuJoCo's is (x, y, z, qw, qx, qy, qz) with a world-frame linear
  velocity: ``robots/conventions.py`` converts.
* A body without joints is welded to its parent: its inertia is appended to the parent's
  Pinocchio joint at its pose in that joint's frame, and it gets a ``FIXED_JOINT`` frame
  ``<body>_fixed`` (as the parser names it) followed by its ``BODY`` frame.

Frames: every joint a ``JOINT`` frame, every body a ``BODY`` frame and every site an ``OP_FRAME``
frame, named as in MuJoCo (unnamed ones get ``joint<id>``, ``body<id>``, ``site<id>``).
"""

from __future__ import annotations

from collections.abc import Iterable

import mujoco
import numpy as np
import pinocchio as pin

from mbctl.robots.exceptions import ModelMismatchError
from mbctl.robots.model_size import check_robot_dof
from mbctl.robots.scene import tree_roots

#: Tolerance on a unit joint axis for using Pinocchio's axis-aligned joint types (RX, PY, ...):
#: MuJoCo normalizes axes at compile time, so an aligned axis is exact up to round-off.
AXIS_ALIGNED_ATOL = 1e-12

_INF = float("inf")
_DOUBLE_MAX = float(np.finfo(float).max)  # Pinocchio's default "no limit" on free and ball joints

_REVOLUTE_ALIGNED = (pin.JointModelRX, pin.JointModelRY, pin.JointModelRZ)
_PRISMATIC_ALIGNED = (pin.JointModelPX, pin.JointModelPY, pin.JointModelPZ)


def pin_model_from_mj(m: mujoco.MjModel, bodies: Iterable[int] | None = None) -> pin.Model:
    """Build the Pinocchio model of a compiled MuJoCo model (kinematics, inertias, joint data).

    Joints are added in MuJoCo's joint order, so q and v have MuJoCo's layout (up to the
    free-flyer and ball quaternion order and the free-flyer velocity frame, see
    ``robots/conventions.py``) when every body with a joint is included. The model also gets
    MuJoCo's gravity (``opt.gravity``), armature (``dof_armature``), viscous damping
    (``dof_damping``), dry friction (``dof_frictionloss``), position limits (``jnt_range`` of
    limited hinge and slide joints; ``+-inf`` when unlimited, Pinocchio's defaults on free and
    ball joints), effort limits (``jnt_actfrcrange`` when ``jnt_actfrclimited``, else ``+-inf``),
    and the reference configurations ``"qpos0"`` and one per keyframe (Pinocchio convention).

    Args:
        m: Compiled MuJoCo model.
        bodies: MuJoCo ids of the bodies to include (e.g. ``articulated_bodies(m)`` to leave out
            static and mocap scenery); each body's parent must be included too (or be the world,
            id 0, which is never a body of the result). Default: every body except the world.

    Returns:
        A new ``pin.Model``: one Pinocchio joint per MuJoCo joint (same names), a ``BODY`` frame
        per body, an ``OP_FRAME`` per site of the included bodies.

    Raises:
        ModelMismatchError: ``bodies`` holds an id that is not a body or the world, or a body
            without its parent; or the model uses what Pinocchio cannot represent with the same
            q: a hinge or slide joint with a non-zero reference position (``ref``, so that
            ``qpos0`` is not zero), or a free joint that is not its body's first joint.
        SizeLimitError: The included bodies have more than ``MAX_ROBOT_DOF`` degrees of freedom.
    """
    included = _checked_bodies(m, bodies)
    check_robot_dof(sum(int(m.body_dofnum[b]) for b in included), _model_name(m))
    model = pin.Model()
    model.name = _model_name(m)
    model.gravity = pin.Motion(np.array(m.opt.gravity, dtype=float), np.zeros(3))

    nbody = int(m.nbody)
    joint_of_body = [0] * nbody  # Pinocchio joint each body's frame is attached to
    X_JB_of_body = [pin.SE3.Identity() for _ in range(nbody)]  # body frame in that joint's frame
    frame_of_body = [0] * nbody  # Pinocchio frame id of each body (world: "universe")
    armature: list[float] = []

    for b in sorted(included):
        p = int(m.body_parentid[b])
        body_name = _name(m, mujoco.mjtObj.mjOBJ_BODY, b, "body")
        parent_joint = joint_of_body[p]
        X_JB = X_JB_of_body[p] * _se3(m.body_pos[b], m.body_quat[b])  # pre-joint body frame
        previous_frame = frame_of_body[p]
        first_jnt = int(m.body_jntadr[b])
        for j in range(first_jnt, first_jnt + int(m.body_jntnum[b])):
            kind = mujoco.mjtJoint(int(m.jnt_type[j]))
            if kind == mujoco.mjtJoint.mjJNT_FREE:
                if j != first_jnt or parent_joint != 0:
                    raise ModelMismatchError(
                        f"Free joint {_name(m, mujoco.mjtObj.mjOBJ_JOINT, j, 'joint')!r} of body "
                        f"{body_name!r} must be its body's first joint, in a body fixed to the world; "
                        "move the other joints to a child body."
                    )
                X_JB = pin.SE3.Identity()  # MuJoCo sets the world pose from qpos directly
            anchor = (
                np.array(m.jnt_pos[j], dtype=float)
                if kind in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_BALL)
                else np.zeros(3)
            )
            joint_id = _add_joint(model, m, j, kind, parent_joint, X_JB * _translation(anchor))
            previous_frame = model.addJointFrame(joint_id, previous_frame)
            dofs = slice(int(m.jnt_dofadr[j]), int(m.jnt_dofadr[j]) + model.joints[joint_id].nv)
            armature.extend(float(a) for a in m.dof_armature[dofs])
            parent_joint = joint_id
            X_JB = _translation(-anchor)
        if m.body_jntnum[b] == 0:
            previous_frame = model.addFrame(
                pin.Frame(
                    f"{body_name}_fixed", parent_joint, previous_frame, X_JB, pin.FrameType.FIXED_JOINT
                ),
                False,
            )
        model.appendBodyToJoint(parent_joint, _inertia(m, b), X_JB)
        frame_of_body[b] = model.addBodyFrame(body_name, parent_joint, X_JB, previous_frame)
        joint_of_body[b] = parent_joint
        X_JB_of_body[b] = X_JB
        for s in np.flatnonzero(m.site_bodyid == b):
            site_name = _name(m, mujoco.mjtObj.mjOBJ_SITE, int(s), "site")
            X_JS = X_JB * _se3(m.site_pos[s], m.site_quat[s])
            model.addFrame(
                pin.Frame(site_name, parent_joint, frame_of_body[b], X_JS, pin.FrameType.OP_FRAME),
                False,
            )

    model.armature = np.array(armature, dtype=float)
    _add_reference_configurations(model, m, included)
    return model


def articulated_bodies(m: mujoco.MjModel) -> set[int]:
    """Ids of the bodies in trees with at least one joint: the robot(s), not the static scenery.

    A tree is a child of the world with all its descendants. Trees without joints (a static
    table, a mocap target) are left out; a jointless robot base is kept when its tree has joints.

    Args:
        m: Compiled MuJoCo model.

    Returns:
        Body ids (the world, 0, never among them).
    """
    root = tree_roots(m)
    jointed = {int(root[b]) for b in range(1, int(m.nbody)) if m.body_jntnum[b] > 0}
    return {b for b in range(1, int(m.nbody)) if int(root[b]) in jointed}


# ---------------------------------------------------------------------------------- helpers
def _checked_bodies(m: mujoco.MjModel, bodies: Iterable[int] | None) -> set[int]:
    nbody = int(m.nbody)
    if bodies is None:
        return set(range(1, nbody))
    included = {int(b) for b in bodies} - {0}
    bad = sorted(b for b in included if not 0 < b < nbody)
    if bad:
        raise ModelMismatchError(
            f"bodies holds ids {bad} that are not bodies of the MuJoCo model (valid: 1 to {nbody - 1}, "
            "the world 0 is implied); pass MuJoCo body ids, e.g. from articulated_bodies(m)."
        )
    orphans = sorted(b for b in included if int(m.body_parentid[b]) not in included | {0})
    if orphans:
        names = [
            f"{_name(m, mujoco.mjtObj.mjOBJ_BODY, b, 'body')} (parent "
            f"{_name(m, mujoco.mjtObj.mjOBJ_BODY, int(m.body_parentid[b]), 'body')})"
            for b in orphans[:5]
        ]
        raise ModelMismatchError(
            f"bodies must include each body's parent; missing the parents of {', '.join(names)}. "
            "Pass whole trees, e.g. articulated_bodies(m)."
        )
    return included


def _model_name(m: mujoco.MjModel) -> str:
    raw = bytes(m.names)
    return raw[: raw.index(b"\0")].decode() if b"\0" in raw else raw.decode()


def _name(m: mujoco.MjModel, obj: mujoco.mjtObj, i: int, prefix: str) -> str:
    return mujoco.mj_id2name(m, obj, i) or f"{prefix}{i}"


def _rotation(quat_wxyz: np.ndarray) -> np.ndarray:
    R = np.zeros(9)
    q = np.array(quat_wxyz, dtype=float)
    mujoco.mju_quat2Mat(R, q / np.linalg.norm(q))
    return R.reshape(3, 3)


def _se3(pos: np.ndarray, quat_wxyz: np.ndarray) -> pin.SE3:
    return pin.SE3(_rotation(quat_wxyz), np.array(pos, dtype=float))


def _translation(p: np.ndarray) -> pin.SE3:
    return pin.SE3(np.eye(3), np.array(p, dtype=float))


def _inertia(m: mujoco.MjModel, b: int) -> pin.Inertia:
    """Spatial inertia of body ``b`` in its body frame: principal inertia rotated by ``iquat``."""
    R_BI = _rotation(m.body_iquat[b])
    I_com_B = R_BI @ np.diag(np.array(m.body_inertia[b], dtype=float)) @ R_BI.T
    return pin.Inertia(float(m.body_mass[b]), np.array(m.body_ipos[b], dtype=float), I_com_B)


def _axis_joint(axis: np.ndarray, aligned: tuple, unaligned: type) -> pin.JointModel:
    for i, joint_type in enumerate(aligned):
        if np.allclose(axis, np.eye(3)[i], rtol=0.0, atol=AXIS_ALIGNED_ATOL):
            return joint_type()
    return unaligned(np.array(axis, dtype=float))


def _add_joint(
    model: pin.Model,
    m: mujoco.MjModel,
    j: int,
    kind: mujoco.mjtJoint,
    parent_joint: int,
    X_parent_joint: pin.SE3,
) -> int:
    """Add MuJoCo joint ``j`` to ``model`` with its limits, damping and friction; its id."""
    name = _name(m, mujoco.mjtObj.mjOBJ_JOINT, j, "joint")
    if kind == mujoco.mjtJoint.mjJNT_FREE:
        joint_model: pin.JointModel = pin.JointModelFreeFlyer()
    elif kind == mujoco.mjtJoint.mjJNT_BALL:
        joint_model = pin.JointModelSpherical()
    elif kind == mujoco.mjtJoint.mjJNT_HINGE:
        joint_model = _axis_joint(m.jnt_axis[j], _REVOLUTE_ALIGNED, pin.JointModelRevoluteUnaligned)
    else:
        joint_model = _axis_joint(m.jnt_axis[j], _PRISMATIC_ALIGNED, pin.JointModelPrismaticUnaligned)
    nq, nv = joint_model.nq, joint_model.nv
    one_dof = kind in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE)
    qpos0 = float(m.qpos0[m.jnt_qposadr[j]])
    if one_dof and qpos0 != 0.0:
        raise ModelMismatchError(
            f"Joint {name!r} has reference position ref={qpos0!r} (MuJoCo measures it from there); "
            "Pinocchio joints have no offset, so q would differ. Set ref=0 and move the offset "
            "into the body's pose."
        )
    if one_dof and m.jnt_limited[j]:
        q_min, q_max = np.array([m.jnt_range[j, 0]]), np.array([m.jnt_range[j, 1]])
    elif one_dof:
        q_min, q_max = np.full(1, -_INF), np.full(1, _INF)
    else:
        q_min, q_max = np.full(nq, -_DOUBLE_MAX), np.full(nq, _DOUBLE_MAX)
    if one_dof and m.jnt_actfrclimited[j]:
        effort_min, effort_max = np.full(nv, m.jnt_actfrcrange[j, 0]), np.full(nv, m.jnt_actfrcrange[j, 1])
    else:
        effort_min, effort_max = np.full(nv, -_INF), np.full(nv, _INF)
    dofs = slice(int(m.jnt_dofadr[j]), int(m.jnt_dofadr[j]) + nv)
    friction = np.array(m.dof_frictionloss[dofs], dtype=float)
    return int(
        model.addJoint(
            parent_joint,
            joint_model,
            X_parent_joint,
            name,
            effort_min,
            effort_max,
            np.full(nv, -_INF),
            np.full(nv, _INF),
            q_min,
            q_max,
            -friction,
            friction,
            np.array(m.dof_damping[dofs], dtype=float),
        )
    )


def _add_reference_configurations(model: pin.Model, m: mujoco.MjModel, included: set[int]) -> None:
    """``qpos0`` and each keyframe's qpos as Pinocchio configurations of the included joints."""
    parts: list[tuple[int, int, bool]] = []  # (qposadr, nq, is_ball_or_free)
    for j in range(int(m.njnt)):
        if int(m.jnt_bodyid[j]) in included:
            kind = mujoco.mjtJoint(int(m.jnt_type[j]))
            nq = {mujoco.mjtJoint.mjJNT_FREE: 7, mujoco.mjtJoint.mjJNT_BALL: 4}.get(kind, 1)
            parts.append((int(m.jnt_qposadr[j]), nq, nq > 1))
    configurations = {"qpos0": np.array(m.qpos0)}
    for k in range(int(m.nkey)):
        configurations[_name(m, mujoco.mjtObj.mjOBJ_KEY, k, "key")] = np.array(m.key_qpos[k])
    for name, qpos in configurations.items():
        q = []
        for adr, nq, has_quat in parts:
            block = np.array(qpos[adr : adr + nq], dtype=float)
            if has_quat:  # (w, x, y, z) -> (x, y, z, w) in the last four entries
                block[-4:] = block[[-3, -2, -1, -4]]
            q.append(block)
        model.referenceConfigurations[name] = np.concatenate(q) if q else np.zeros(0)
