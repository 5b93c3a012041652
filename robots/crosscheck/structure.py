"""The cross-check's structure step: joints paired by name, one q and v layout, located differences.

States can be compared only when both engines have the same joints in the same order with the
same q and v slices. A Pinocchio model read from another file (a URDF) is paired with the plant
by name when it is loaded (``robots/joint_pairing.py``: renamed by a joint map, re-rooted on a
free flyer, reordered); what still does not pair is a structure failure naming both sides. For
such a model the report also locates every difference (``robots/model_diff.py``): joint or body,
quantity, both values.
"""

from __future__ import annotations

import mujoco

from mbctl.robots.model_diff import model_differences
from mbctl.robots.model_pair import Robot
from mbctl.robots.pin_from_mj import pin_model_from_mj


def first(names: list[str], limit: int = 8) -> str:
    """``names`` joined with commas, the first ``limit`` of them and how many more."""
    more = f" and {len(names) - limit} more" if len(names) > limit else ""
    return ", ".join(names[:limit]) + more


def structure_problems(robot: Robot) -> list[str]:
    """Why states cannot be mapped between the engines ([] when they can).

    Args:
        robot: The model pair; ``robot.joints`` is the plant's robot, ``robot.pin_model`` the
            analytic model.

    Returns:
        Messages: sizes, joints that do not pair by name (both sides), joints in another order,
        a joint with another q/v layout; with hints (``--joint-map``, ``--floating-base``, the
        first-tree limit of Pinocchio's MJCF parser).
    """
    pm, m = robot.pin_model, robot.mj_model
    problems = []
    nq, nv = robot.converter.nq, robot.converter.nv
    if (pm.nq, pm.nv) != (nq, nv):
        problems.append(f"sizes differ: Pinocchio nq={pm.nq}, nv={pm.nv}; MuJoCo robot nq={nq}, nv={nv}")
    pin_names, mj_names = list(pm.names)[1:], list(robot.joints)
    only_pin = [n for n in pin_names if n not in set(mj_names)]
    only_mj = [n for n in mj_names if n not in set(pin_names)]
    if only_pin or only_mj:
        problems.append(
            f"joints do not pair by name (Pinocchio {len(pin_names)}, MuJoCo {len(mj_names)} joints)"
            + (f"; only in MuJoCo: {first(only_mj)}" if only_mj else "")
            + (f"; only in Pinocchio: {first(only_pin)}" if only_pin else "")
        )
        if only_mj and only_pin:
            problems.append("pair renamed joints with --joint-map PIN=MJCF,... (load_robot(joint_map=...))")
        kinds = [j.kind for j in robot.joints.values()]
        pin_free = pm.njoints > 1 and pm.joints[1].shortname() == "JointModelFreeFlyer"
        if kinds[:1] == ["free"] and only_mj[:1] == mj_names[:1] and not pin_free:
            problems.append(
                f"the plant's robot has a free joint ({mj_names[0]!r}) and the Pinocchio model is "
                "fixed-base: add a free flyer with --floating-base (floating_base=True)"
            )
        problems += _first_tree_hint(robot, m, len(pin_names) < len(mj_names))
    elif pin_names != mj_names:
        problems.append(_tree_difference(robot, pin_names, mj_names))
    else:
        for k, j in enumerate(robot.joints.values(), start=1):
            pj = pm.joints[k]
            if (pj.idx_q, pj.idx_v, pj.nq, pj.nv) != (j.idx_q, j.idx_v, j.nq, j.nv):
                problems.append(
                    f"joint {j.name!r} (MuJoCo {j.kind}) has q[{j.idx_q}:+{j.nq}] v[{j.idx_v}:+{j.nv}] "
                    f"in MuJoCo but q[{pj.idx_q}:+{pj.nq}] v[{pj.idx_v}:+{pj.nv}] in Pinocchio "
                    f"({pj.shortname()})"
                )
                break
    return problems


def _tree_difference(robot: Robot, pin_names: list[str], mj_names: list[str]) -> str:
    """Joints that pair by name but not in order: the first joint whose parent joint differs."""
    pm, plant = robot.pin_model, pin_model_from_mj(robot.mj_model, set(robot.robot_body_ids))
    for j in range(1, plant.njoints):
        name = plant.names[j]
        a, b = pm.names[pm.parents[pm.getJointId(name)]], plant.names[plant.parents[j]]
        if a != b:
            return f"joint {name!r}: parent {a!r} in Pinocchio, {b!r} in MuJoCo (the trees differ)"
    k = next(i for i, (a, b) in enumerate(zip(pin_names, mj_names, strict=True)) if a != b)
    return (f"the joints pair by name but come in another order: #{k} is {pin_names[k]!r} in Pinocchio, "
            f"{mj_names[k]!r} in MuJoCo")


def _first_tree_hint(robot: Robot, m: mujoco.MjModel, fewer_in_pin: bool) -> list[str]:
    """Pinocchio 4.1's MJCF parser builds only the first body tree: say so when that explains it.

    Only when Pinocchio has fewer joints and the robot has several trees, or a scene body comes
    first (mocap targets and scenery after it do not matter).
    """
    tops = [b for b in range(1, m.nbody) if m.body_parentid[b] == 0]
    robot_tops = [b for b in tops if b in set(robot.robot_body_ids)]
    first_is_scene = bool(tops) and tops[0] not in robot_tops
    if not fewer_in_pin or not (len(robot_tops) > 1 or first_is_scene):
        return []
    return [
        f"the robot has {len(robot_tops)} body trees under <worldbody>"
        + (" after a scene body" if first_is_scene else "")
        + ", and Pinocchio 4.1's MJCF parser builds only the first body tree: put the robot "
        "first, or give the Pinocchio side its own file (--pin-model / pin_model_file), or use "
        "--analytic mujoco"
    ]


def located_differences(robot: Robot, limit: int = 12) -> list[str]:
    """Where a Pinocchio model read from a file differs from the plant's robot: one note, or none.

    Only for the parser path (a model built from the compiled plant agrees by construction).
    """
    if robot.source.analytic != "parser":
        return []
    plant = pin_model_from_mj(robot.mj_model, set(robot.robot_body_ids))
    found = model_differences(robot.pin_model, plant, ("Pinocchio", "MuJoCo"))
    if not found:
        return []
    more = f"; and {len(found) - limit} more" if len(found) > limit else ""
    return [f"the models differ (Pinocchio vs MuJoCo, at q0, world frame): {'; '.join(found[:limit])}{more}"]
