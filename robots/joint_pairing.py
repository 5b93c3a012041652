"""The joints of a Pinocchio model read from another file (a URDF) paired with the plant's, by name.

A URDF and the MJCF made from it describe one robot but need not list its joints in the same
order (a quadruped's legs, a humanoid's arms), nor name them alike, nor agree on the base (a
fixed-base URDF of a robot whose MJCF root has a free joint). The analytic model must have the
plant's q and v layout (``robots/conventions.py`` maps the two engines by index), so the parsed
model is rebuilt:

* joints renamed by a joint map ``{name in the Pinocchio file: name in the plant}``;
* a free flyer added at the body that holds the plant's free joint when the file has none
  (automatically, or on request), named as the plant's free joint;
* continuous joints (Pinocchio's unbounded revolute, nq = 2: cos, sin) made revolute joints
  without limits (nq = 1), as MuJoCo's hinges are, when the plant's joint of that name is a hinge;
* joints put in the plant's order, which is possible whenever the trees agree (both orders list
  parents before children);
* each body of a renamed joint named as the plant's body of that joint, so that its kinematics
  are compared too.

Joints that do not pair are left as they are: the cross-check's structure test then lists both
sides. Written here because Pinocchio has no function to rename, reorder or re-root a model.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from mbctl.robots.exceptions import JointMapError, UnknownNameError

_FREE = "JointModelFreeFlyer"
_UNBOUNDED = {
    "JointModelRUBX": pin.JointModelRX,
    "JointModelRUBY": pin.JointModelRY,
    "JointModelRUBZ": pin.JointModelRZ,
}


@dataclass(frozen=True)
class Pairing:
    """A Pinocchio model with the plant's joint names and order, and what was changed.

    Attributes:
        model: The rebuilt model (the parsed model itself when nothing had to change).
        edits: What was done, one sentence each (for ``ModelSource.edits`` and reports).
    """

    model: pin.Model
    edits: tuple[str, ...]


def parse_joint_map(text: str) -> dict[str, str]:
    """A joint map from ``"A=B,C=D"`` or from a file of ``A=B`` lines (``#`` starts a comment).

    ``A`` is a joint name in the Pinocchio model's file (e.g. the URDF), ``B`` the plant's.

    Raises:
        JointMapError: An entry that is not ``A=B``, a name given twice on either side, or a file that
            cannot be read (not text).
    """
    path = Path(text).expanduser()
    if path.is_file():
        origin = f"joint map file {str(path)!r}"
        try:
            lines = path.read_text().splitlines()
        except (OSError, UnicodeDecodeError) as exc:
            raise JointMapError(f"{origin} cannot be read ({exc}); give PIN_JOINT=PLANT_JOINT lines, or the "
                                "pairs inline, comma-separated") from None
        entries = [line.split("#", 1)[0].strip() for line in lines]
    else:
        entries = [part.strip() for part in text.split(",")]
        origin = f"joint map {text!r}"
    out: dict[str, str] = {}
    for entry in (e for e in entries if e):
        a, sep, b = (s.strip() for s in entry.partition("="))
        if not sep or not a or not b:
            raise JointMapError(
                f"{origin}: {entry!r} is not PIN_JOINT=PLANT_JOINT (a joint of the Pinocchio file, "
                "then the plant's joint of that robot), e.g. thumb_0=joint_12.0; give a file of "
                "such lines or a comma-separated list"
            )
        if a in out:
            raise JointMapError(f"{origin}: joint {a!r} is mapped twice ({out[a]!r} and {b!r})")
        if b in out.values():
            raise JointMapError(f"{origin}: plant joint {b!r} is the target of two joints")
        out[a] = b
    return out


def pair_joints(
    parsed: pin.Model,
    plant: pin.Model,
    joint_map: Mapping[str, str] | None = None,
    floating_base: bool | None = None,
    unnamed: Collection[str] = (),
) -> Pairing:
    """Rebuild ``parsed`` with the joint names, base and joint order of ``plant``.

    Args:
        parsed: The Pinocchio model read from the user's file (URDF or MJCF).
        plant: The plant's robot as a Pinocchio model (``pin_model_from_mj``): its joint names
            and order lead.
        joint_map: ``{joint of parsed: joint of plant}`` for joints named differently.
        floating_base: True adds a free flyer to a fixed-base ``parsed``; False never adds one;
            None (default) adds one when the plant's robot has a free root joint and ``parsed``
            has none.
        unnamed: Plant joints that have no name in the MJCF (``pin_model_from_mj`` calls them
            ``joint<id>``): each is paired with the parsed joint that moves the body of the same
            name, as nothing else can pair them.

    Returns:
        The rebuilt model and what was done.

    Raises:
        UnknownNameError: A joint map entry naming a joint that ``parsed`` (key) or the plant
            (value) does not have.
    """
    joint_map = dict(joint_map or {})
    parsed_names, plant_names = list(parsed.names)[1:], list(plant.names)[1:]
    for a, b in joint_map.items():
        if a not in parsed_names:
            raise UnknownNameError("joint of the Pinocchio model (joint map key)", a, parsed_names)
        if b not in plant_names:
            raise UnknownNameError("joint of the plant (joint map value)", b, plant_names)
    edits: list[str] = []
    plant_free = plant.njoints > 1 and plant.joints[1].shortname() == _FREE
    parsed_free = [j for j in range(1, parsed.njoints) if parsed.parents[j] == 0
                   and parsed.joints[j].shortname() == _FREE]
    root = _Root()
    if not parsed_free and (floating_base is True or (floating_base is None and plant_free)):
        root = _free_flyer_root(parsed, plant if plant_free else None, forced=floating_base is True)
        if root.description:
            edits.append(root.description)
    names = {j: joint_map.get(n, n) for j, n in enumerate(parsed_names, start=1)}
    if parsed_free and plant_free and parsed_names[parsed_free[0] - 1] not in joint_map:
        names[parsed_free[0]] = plant.names[1]  # the free flyers pair whatever their names
    through_bodies = _pair_unnamed(parsed, plant, names, set(unnamed))
    if through_bodies:
        edits.append("unnamed MuJoCo joints paired through the bodies they move: " + ", ".join(
            f"{parsed.names[j]} -> {names[j]} ({body!r})" for j, body in through_bodies.items()))
    renamed = {parsed.names[j]: n for j, n in names.items() if n != parsed.names[j]}
    if renamed:
        edits.append("joints renamed: " + ", ".join(f"{a} -> {b}" for a, b in renamed.items()))
    order = _plant_order(parsed, plant, names, root.name)
    if order != sorted(names) and order is not None:
        edits.append(f"joints put in the plant's order ({_moved(parsed, order)})")
    continuous = [j for j in names if parsed.joints[j].shortname() in _UNBOUNDED
                  or parsed.joints[j].shortname() == "JointModelRevoluteUnboundedUnaligned"]
    continuous = [j for j in continuous if plant.existJointName(names[j])
                  and plant.joints[plant.getJointId(names[j])].nq == 1]
    if continuous:
        edits.append("continuous joints made revolute without limits (nq 1, as MuJoCo's hinges): "
                      + ", ".join(names[j] for j in continuous))
    if not edits:
        return Pairing(parsed, ())
    bodies = _body_names(parsed, plant, names, renamed)
    if bodies:
        edits.append("bodies of renamed joints named as the plant's: "
                     + ", ".join(f"{a} -> {b}" for a, b in bodies.items()))
    model = _rebuild(parsed, order or sorted(names), names, root, set(continuous), bodies)
    return Pairing(model, tuple(edits))


@dataclass(frozen=True)
class _Root:
    """A free flyer to add: its name, its pose ``X_0F`` in the parsed model's root, and why."""

    name: str = ""
    X_0F: pin.SE3 | None = None
    description: str = ""


def _free_flyer_root(parsed: pin.Model, plant: pin.Model | None, forced: bool) -> _Root:
    """The free flyer at the parsed frame named as the plant's free body.

    Without such a frame: at the parsed model's root when ``forced``, else none (an empty
    ``_Root``: the trees differ, and the structure check says so).
    """
    if plant is None:
        return _Root("root_joint", pin.SE3.Identity(),
                     "free flyer 'root_joint' added at the root of the Pinocchio model (floating base "
                     "requested; the plant's robot has no free joint)")
    body = _first_body(plant, 1) or ""
    name = plant.names[1]
    fixed = [f for f in parsed.frames if f.name == body and f.parentJoint == 0]
    if fixed:
        return _Root(name, fixed[0].placement.copy(),
                     f"free flyer {name!r} added at {body!r} (the Pinocchio model is fixed-base; the "
                     f"plant's {body!r} has a free joint)")
    if not forced:
        return _Root()
    return _Root(name, pin.SE3.Identity(),
                 f"free flyer {name!r} added at the root of the Pinocchio model (floating base requested; "
                 f"the plant's free body {body!r} has no frame of that name in it, so its pose may differ)")


def _first_body(model: pin.Model, j: int) -> str | None:
    """The name of the first body (BODY frame) joint ``j`` moves, or None."""
    return next((f.name for f in model.frames if f.type == pin.FrameType.BODY and f.parentJoint == j), None)


def _pair_unnamed(
    parsed: pin.Model, plant: pin.Model, names: dict[int, str], unnamed: set[str]
) -> dict[int, str]:
    """Rename in ``names`` the parsed joints that move the body of an unnamed plant joint.

    Returns:
        ``{parsed joint id: body name}`` of the joints paired this way.
    """
    taken = set(names.values())
    plant_names = set(list(plant.names)[1:])
    out: dict[int, str] = {}
    for name in sorted(unnamed - taken):
        body = _first_body(plant, plant.getJointId(name)) if plant.existJointName(name) else None
        if body is None:
            continue
        candidates = [j for j, n in names.items() if n not in plant_names and _first_body(parsed, j) == body]
        if len(candidates) == 1:
            names[candidates[0]] = name
            out[candidates[0]] = body
    return out


def _plant_order(
    parsed: pin.Model, plant: pin.Model, names: dict[int, str], free_name: str
) -> list[int] | None:
    """Parsed joint ids in the plant's joint order.

    None when the names do not pair, or when the plant's order would put a joint before its
    parent in ``parsed`` (the trees differ).
    """
    by_name = {n: j for j, n in names.items()}
    plant_names = [n for n in list(plant.names)[1:] if n != free_name]
    if sorted(plant_names) != sorted(by_name):
        return None
    order = [by_name[n] for n in plant_names]
    position = {j: k for k, j in enumerate(order)}
    if any(parsed.parents[j] != 0 and position[parsed.parents[j]] > position[j] for j in order):
        return None  # the trees differ; the structure check and model differences say where
    return order


def _moved(parsed: pin.Model, order: list[int]) -> str:
    first = next(k for k, j in enumerate(order) if j != k + 1)
    return f"first moved: {parsed.names[order[first]]!r} to position {first}"


def _body_names(
    parsed: pin.Model, plant: pin.Model, names: dict[int, str], renamed: dict[str, str]
) -> dict[str, str]:
    """``{parsed body: plant body}`` for the first body of each renamed joint.

    Only where both bodies exist and the plant's name is not taken in ``parsed``.
    """
    taken = {f.name for f in parsed.frames}
    out = {}
    for j, new in names.items():
        if parsed.names[j] not in renamed or not plant.existJointName(new):
            continue
        jp = plant.getJointId(new)
        a, b = _first_body(parsed, j), _first_body(plant, jp)
        if a and b and a != b and b not in taken:
            out[a] = b
    return out


def _rebuild(
    parsed: pin.Model,
    order: list[int],
    names: dict[int, str],
    root: _Root,
    continuous: set[int],
    bodies: dict[str, str],
) -> pin.Model:
    """``parsed`` with joints in ``order``, renamed, re-rooted on ``root`` and de-wrapped."""
    model = pin.Model()
    model.name = parsed.name
    model.gravity = parsed.gravity
    joint_ids = {0: 0}
    armature: list[float] = []
    X_F0 = root.X_0F.inverse() if root.X_0F is not None else None
    if X_F0 is not None:  # the root's bodies (and their inertia) ride on the free flyer
        joint_ids[0] = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), root.name)
        model.appendBodyToJoint(joint_ids[0], X_F0.act(parsed.inertias[0]), pin.SE3.Identity())
        armature += [0.0] * 6
    else:  # a fixed base: the root link's inertia (a URDF's base link) stays on the universe
        model.inertias[0] = parsed.inertias[0].copy()
    for j in order:
        parent = int(parsed.parents[j])
        placement = parsed.jointPlacements[j]
        if parent == 0 and X_F0 is not None:
            placement = X_F0 * placement
        jm, q = parsed.joints[j], slice(parsed.idx_qs[j], parsed.idx_qs[j] + parsed.nqs[j])
        v = slice(parsed.idx_vs[j], parsed.idx_vs[j] + parsed.nvs[j])
        joint_model, q_min, q_max = jm, parsed.lowerPositionLimit[q], parsed.upperPositionLimit[q]
        if j in continuous:
            joint_model = _bounded(jm)
            q_min, q_max = np.full(1, -np.inf), np.full(1, np.inf)
        joint_ids[j] = model.addJoint(
            joint_ids[parent], joint_model, placement, names[j],
            parsed.lowerEffortLimit[v], parsed.upperEffortLimit[v],
            parsed.lowerVelocityLimit[v], parsed.upperVelocityLimit[v], q_min, q_max,
            parsed.lowerDryFrictionLimit[v], parsed.upperDryFrictionLimit[v], parsed.damping[v],
        )
        model.appendBodyToJoint(joint_ids[j], parsed.inertias[j], pin.SE3.Identity())
        armature += np.asarray(parsed.armature[v], dtype=float).tolist()
    frame_ids = {0: 0}
    if X_F0 is not None:
        frame_ids[0] = model.addFrame(
            pin.Frame(root.name, joint_ids[0], 0, pin.SE3.Identity(), pin.FrameType.JOINT), False
        )
    for f in range(1, parsed.nframes):
        frame = parsed.frames[f]
        joint = int(frame.parentJoint)
        placement = frame.placement if joint != 0 or X_F0 is None else X_F0 * frame.placement
        name = frame.name
        if frame.type == pin.FrameType.JOINT and joint > 0 and name == parsed.names[joint]:
            name = names[joint]
        elif frame.type == pin.FrameType.BODY:
            name = bodies.get(name, name)
        frame_ids[f] = model.addFrame(
            pin.Frame(name, joint_ids[joint], frame_ids[int(frame.parentFrame)], placement, frame.type,
                      frame.inertia),
            False,  # the joints' inertias above already hold every body
        )
    model.armature = np.array(armature, dtype=float)
    return model


def _bounded(jm: pin.JointModel) -> pin.JointModel:
    """The revolute joint (nq 1) about the axis of an unbounded one (nq 2)."""
    short = jm.shortname()
    if short in _UNBOUNDED:
        return _UNBOUNDED[short]()
    data = jm.createData()
    jm.calc(data, np.array([1.0, 0.0]))
    return pin.JointModelRevoluteUnaligned(np.array(data.S)[3:6].ravel())
