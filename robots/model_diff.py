"""Where two models of one robot differ, located: the joint or body, the quantity, both values.

Used wherever two descriptions must be the same robot: a scene and the robot file it should hold
(``registry.load_robot``), and a Pinocchio model from another file (a URDF) against the plant
(the cross-check's notes). Both sides are Pinocchio models whose joints carry the same names (see
``robots/joint_pairing.py``); the MuJoCo side is built from the compiled plant
(``pin_model_from_mj``). Everything is compared at the neutral configuration q0, in world
coordinates, so that joint and body frames placed differently on the same mechanism (a URDF
joint origin, an MJCF body frame) are not differences:

* joints, by name: presence, parent joint, kind (hinge, slide, ball, free, ...), nq and nv;
* each joint's motion axes at q0: its columns of the world-frame Jacobian ``[v_O; w_O]``
  (Plücker coordinates; where a hinge's frame sits along its axis does not matter);
* the inertia each joint carries (its bodies and the bodies welded to them): mass, centre of
  mass ``p_WC`` and rotational inertia about it in world axes;
* with ``bodies=True``, the body names and the pose at q0 of every body both models have.

Written here because Pinocchio compares models only for exact equality (``Model.__eq__``), without
saying where they differ and without tolerating frame conventions.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin

#: Relative tolerance on masses and inertias, absolute tolerance [m] on positions and [-] on unit
#: axes and rotation entries: both sides come from the same decimal strings, so anything beyond
#: round-off is a real difference (as the load-time check, ``agreement``).
RTOL = 1e-9
ATOL = 1e-9

_KINDS = {
    "JointModelRX": "hinge", "JointModelRY": "hinge", "JointModelRZ": "hinge",
    "JointModelRevoluteUnaligned": "hinge",
    "JointModelRUBX": "continuous hinge", "JointModelRUBY": "continuous hinge",
    "JointModelRUBZ": "continuous hinge", "JointModelRevoluteUnboundedUnaligned": "continuous hinge",
    "JointModelPX": "slide", "JointModelPY": "slide", "JointModelPZ": "slide",
    "JointModelPrismaticUnaligned": "slide",
    "JointModelSpherical": "ball", "JointModelFreeFlyer": "free",
}


def joint_kind(model: pin.Model, j: int) -> str:
    """The kind of joint ``j`` in MuJoCo's words: "hinge", "slide", "ball", "free", ..."""
    short = model.joints[j].shortname()
    return _KINDS.get(short, short.removeprefix("JointModel"))


def model_differences(
    a: pin.Model, b: pin.Model, labels: Sequence[str] = ("Pinocchio", "MuJoCo"), *, bodies: bool = False
) -> list[str]:
    """Every difference between two models of one robot, located and with both values.

    Args:
        a: One model (e.g. Pinocchio's, from a URDF).
        b: The other (e.g. built from the compiled MuJoCo plant); its joint order leads.
        labels: Names of ``a`` and ``b`` in the messages.
        bodies: Also compare body names (BODY frames) and the pose at q0 of the bodies both have.

    Returns:
        Messages such as "link2 (joint 'elbow'): mass 1.2 vs 1.1 kg" (a joint is located by the
        bodies it carries in ``b``) or "joints do not pair by name: only in MuJoCo: j2"; values
        in the order (a, b). Empty when the models agree.
    """
    out: list[str] = []
    names_a, names_b = list(a.names)[1:], list(b.names)[1:]
    unpaired = _only_in(names_a, names_b, labels)
    if unpaired:
        out.append(f"joints do not pair by name: {unpaired}")
    if bodies:
        unpaired = _only_in(list(_body_frames(a)), list(_body_frames(b)), labels)
        if unpaired:
            out.append(f"bodies differ: {unpaired}")
    da, db = _at_neutral(a), _at_neutral(b)
    for jb, name in enumerate(names_b, start=1):
        if not a.existJointName(name):
            continue
        ja = a.getJointId(name)
        out += _joint_differences(a, b, ja, jb, da, db, labels)
    if bodies:
        frames_a = _body_frames(a)
        for name, fb in _body_frames(b).items():
            if name in frames_a:
                out += _pose_difference(f"body {name!r}", da.oMf[frames_a[name]], db.oMf[fb])
    return out


def _only_in(names_a: list[str], names_b: list[str], labels: Sequence[str]) -> str:
    """"only in A: x, y; only in B: z" for the names of one list missing from the other ("" if none)."""
    only = ((labels[0], [n for n in names_a if n not in set(names_b)]),
            (labels[1], [n for n in names_b if n not in set(names_a)]))
    return "; ".join(f"only in {label}: {_listing(names)}" for label, names in only if names)


def _listing(names: list[str], limit: int = 8) -> str:
    more = f" and {len(names) - limit} more" if len(names) > limit else ""
    return ", ".join(names[:limit]) + more


def _body_frames(model: pin.Model) -> dict[str, int]:
    return {f.name: k for k, f in enumerate(model.frames) if f.type == pin.FrameType.BODY and k > 0}


def _where(model: pin.Model, j: int) -> str:
    """Joint ``j`` located by the bodies it carries: "link2, ee_body (joint 'elbow')"."""
    names = [f.name for f in model.frames if f.type == pin.FrameType.BODY and f.parentJoint == j]
    joint = f"joint {model.names[j]!r}"
    return f"{', '.join(names)} ({joint})" if names else joint


def _at_neutral(model: pin.Model) -> pin.Data:
    data = model.createData()
    q0 = pin.neutral(model)
    pin.computeJointJacobians(model, data, q0)  # also the joint placements oMi
    pin.updateFramePlacements(model, data)
    return data


def _vec(x: np.ndarray, digits: int = 6) -> str:
    """``(0.3, 0, 0.4)``: ``digits`` significant digits, round-off below 1e-12 and -0 shown as 0."""
    values = np.asarray(x, dtype=float).ravel()
    values = np.where(np.abs(values) < 1e-12, 0.0, values) + 0.0
    return "(" + ", ".join(f"{v:.{digits}g}" for v in values) + ")"


def _versus(a: float | np.ndarray, b: float | np.ndarray, unit: str) -> str:
    """``"a vs b unit"`` with the fewest digits (6 or more) that show the two values apart."""
    scalar = np.ndim(a) == 0
    for digits in range(6, 18):
        text_a, text_b = (f"{float(a):.{digits}g}", f"{float(b):.{digits}g}") if scalar else (
            _vec(np.asarray(a), digits), _vec(np.asarray(b), digits))
        if text_a != text_b:
            break
    return f"{text_a} vs {text_b} {unit}"


def _joint_differences(
    a: pin.Model, b: pin.Model, ja: int, jb: int, da: pin.Data, db: pin.Data, labels: Sequence[str]
) -> list[str]:
    la, lb = labels
    where = _where(b, jb)
    parent_a, parent_b = a.names[a.parents[ja]], b.names[b.parents[jb]]
    if parent_a != parent_b:
        return [f"{where}: parent joint {parent_a!r} in {la}, {parent_b!r} in {lb}"]
    kind_a, kind_b = joint_kind(a, ja), joint_kind(b, jb)
    ja_, jb_ = a.joints[ja], b.joints[jb]
    if kind_a != kind_b or (ja_.nq, ja_.nv) != (jb_.nq, jb_.nv):
        return [f"{where}: {kind_a} (nq {ja_.nq}, nv {ja_.nv}) in {la}, "
                f"{kind_b} (nq {jb_.nq}, nv {jb_.nv}) in {lb}"]
    out = []
    S_a = np.asarray(da.J).reshape(6, -1)[:, ja_.idx_v : ja_.idx_v + ja_.nv]  # (6,) when nv = 1
    S_b = np.asarray(db.J).reshape(6, -1)[:, jb_.idx_v : jb_.idx_v + jb_.nv]
    if not np.allclose(S_a, S_b, rtol=0.0, atol=ATOL):
        out.append(f"{where}: {_axis_words(S_a, kind_a)} vs {_axis_words(S_b, kind_b)}")
    out += _inertia_differences(where, da.oMi[ja].act(a.inertias[ja]), db.oMi[jb].act(b.inertias[jb]))
    return out


def _axis_words(S: np.ndarray, kind: str) -> str:
    """A joint's motion axes at q0 in words: a hinge's axis and a point on it, a slide's axis."""
    if S.shape[1] == 1 and "hinge" in kind:
        v_O, w = S[:3, 0], S[3:, 0]
        p = np.cross(w, v_O) / max(float(w @ w), 1e-300)  # the point of the axis nearest the origin
        return f"axis {_vec(w)} through {_vec(p)} m at q0"
    if S.shape[1] == 1 and kind == "slide":
        return f"axis {_vec(S[:3, 0])} at q0"
    return f"motion axes at q0 (world Jacobian columns [v_O; w]) {_vec(S.T)}"


def _inertia_differences(where: str, I_a: pin.Inertia, I_b: pin.Inertia) -> list[str]:
    """Mass, centre of mass (world) and rotational inertia about it (world axes), at q0."""
    out = []
    if not np.isclose(I_a.mass, I_b.mass, rtol=RTOL, atol=1e-12):
        out.append(f"{where}: mass {_versus(I_a.mass, I_b.mass, 'kg')}")
    if max(I_a.mass, I_b.mass) > 0 and not np.allclose(I_a.lever, I_b.lever, rtol=0.0, atol=ATOL):
        out.append(f"{where}: centre of mass at q0 {_versus(I_a.lever, I_b.lever, 'm')}")
    Ia, Ib = np.asarray(I_a.inertia), np.asarray(I_b.inertia)
    scale = max(float(np.abs(Ib).max()), 1e-12)
    if np.abs(Ia - Ib).max() > RTOL * scale:
        r, c = np.unravel_index(int(np.argmax(np.abs(Ia - Ib))), Ia.shape)
        out.append(
            f"{where}: rotational inertia about the centre of mass (world axes at q0), entry ({r}, {c}): "
            f"{_versus(Ia[r, c], Ib[r, c], 'kg m^2')}"
        )
    return out


def _pose_difference(where: str, X_a: pin.SE3, X_b: pin.SE3) -> list[str]:
    out = []
    if not np.allclose(X_a.translation, X_b.translation, rtol=0.0, atol=ATOL):
        out.append(f"{where}: position at q0 {_versus(X_a.translation, X_b.translation, 'm')}")
    if not np.allclose(X_a.rotation, X_b.rotation, rtol=0.0, atol=ATOL):
        angle = float(np.degrees(np.linalg.norm(pin.log3(X_a.rotation.T @ X_b.rotation))))
        out.append(f"{where}: orientation at q0 differs by {angle:.4g} deg")
    return out
