"""Words for an entry of a compared quantity, so that a failing quantity says where it fails.

Per state, each quantity is an array whose axes have fixed roles: ``fk_position`` is (nf, 3)
(frame, world axis), a Jacobian's rows are (nf, 3, nv) (frame, world axis, velocity coordinate),
``mass_matrix`` is (nv, nv), a generalized force is (nv,), a momentum is (3,) and an energy a
scalar. ``describe_entry`` turns an index into such an array into names: the frame ("body
'pelvis'"), the velocity coordinate and its joint ("v[7] (left_knee)"), the axis ("z").
"""

from __future__ import annotations

from collections.abc import Sequence

from mbctl.robots.model_pair import Robot

_AXES = ("x", "y", "z")

#: Role of each axis of a quantity's per-state array (see the module docstring).
ROLES: dict[str, tuple[str, ...]] = {
    "fk_position": ("frame", "axis"),
    "fk_rotation": ("frame", "row", "column"),
    "jacobian_linear": ("frame", "axis", "dof"),
    "jacobian_angular": ("frame", "axis", "dof"),
    "com": ("axis",),
    "com_jacobian": ("axis", "dof"),
    "mass_matrix": ("row dof", "column dof"),
    "gravity": ("dof",),
    "bias": ("dof",),
    "forward_dynamics": ("dof",),
    "inverse_dynamics": ("dof",),
    "kinetic_energy": (),
    "potential_energy": (),
    "momentum_linear": ("axis",),
    "momentum_angular": ("axis",),
}


def dof_labels(robot: Robot) -> list[str]:
    """Label of every velocity coordinate (nv,) in Pinocchio's order, naming its joint.

    Args:
        robot: The model pair; joints and their ``idx_v`` come from the MuJoCo side.

    Returns:
        E.g. ``"v[7] (left_knee)"`` for a 1-dof joint, ``"v[4] (root, dof 4 of 6)"`` for a
        multi-dof joint, ``"v[i]"`` for a coordinate no joint claims.
    """
    labels = [f"v[{i}]" for i in range(robot.nv)]
    for j in robot.joints.values():
        for c in range(j.nv):
            i = j.idx_v + c
            if i < robot.nv:
                labels[i] = f"v[{i}] ({j.name})" if j.nv == 1 else f"v[{i}] ({j.name}, dof {c} of {j.nv})"
    return labels


def describe_entry(
    quantity: str, index: Sequence[int], frame_labels: Sequence[str], dof_labels: Sequence[str]
) -> str:
    """Name the entry ``index`` of one state's array of ``quantity``.

    Args:
        quantity: A key of ``ROLES`` (the names of ``TOLERANCES``).
        index: Index into the quantity's per-state array, one integer per axis.
        frame_labels: Label of each compared frame, e.g. "body 'pelvis'" (nf,).
        dof_labels: Label of each velocity coordinate (nv,), see ``dof_labels``.

    Returns:
        E.g. "body 'pelvis', axis z, column v[7] (left_knee)"; "" for a scalar quantity.

    Raises:
        KeyError: ``quantity`` is not a key of ``ROLES``; the message lists the keys.
    """
    if quantity not in ROLES:
        raise KeyError(f"No quantity {quantity!r}; available: {', '.join(ROLES)}")
    parts = []
    for role, i in zip(ROLES[quantity], index, strict=True):
        if role == "frame":
            parts.append(frame_labels[i])
        elif role == "axis":
            parts.append(f"axis {_AXES[i]}")
        elif role == "dof":
            parts.append(f"column {dof_labels[i]}" if len(ROLES[quantity]) > 1 else dof_labels[i])
        elif role in ("row dof", "column dof"):
            parts.append(f"{role.split()[0]} {dof_labels[i]}")
        else:  # row or column of a rotation matrix
            parts.append(f"{role} {i}")
    return ", ".join(parts)
