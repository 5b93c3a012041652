"""Which bodies of a MuJoCo model are the robot, and which are the scene around it.

A plant may hold more than the robot: a floor, a static wall, a mocap target, a free box on a
table. The robot is the set of kinematic trees (a child of the world with all its descendants)
whose joints the actuators drive; every other body is scene. The analytic model, the state
(q, v) and the load-time checks cover the robot only; the plant keeps the scene's coordinates
and steps them as usual.

Written here because neither MuJoCo nor Pinocchio has the notion: MuJoCo simulates one world,
Pinocchio models one mechanism.
"""

from __future__ import annotations

from collections.abc import Iterable

import mujoco
import numpy as np

from mbctl.robots.exceptions import UnknownNameError
from mbctl.robots.indexing import as_slice


def tree_roots(m: mujoco.MjModel) -> np.ndarray:
    """For every body id, the id of its tree's root (a child of the world); 0 for the world."""
    root = np.zeros(int(m.nbody), dtype=int)
    for b in range(1, int(m.nbody)):  # parents come before children in MuJoCo's body order
        p = int(m.body_parentid[b])
        root[b] = b if p == 0 else root[p]
    return root


def actuated_bodies(m: mujoco.MjModel) -> set[int]:
    """Ids of the bodies an actuator acts on: through a joint, a tendon, a site or a body."""
    out: set[int] = set()
    trn = mujoco.mjtTrn
    for a in range(int(m.nu)):
        kind, ids = int(m.actuator_trntype[a]), [int(i) for i in m.actuator_trnid[a] if i >= 0]
        if kind in (trn.mjTRN_JOINT, trn.mjTRN_JOINTINPARENT):
            out.update(int(m.jnt_bodyid[j]) for j in ids[:1])
        elif kind == trn.mjTRN_TENDON:
            out.update(_tendon_bodies(m, ids[0]))
        elif kind in (trn.mjTRN_SITE, trn.mjTRN_SLIDERCRANK):
            out.update(int(m.site_bodyid[s]) for s in ids)
        elif kind == trn.mjTRN_BODY:
            out.update(ids[:1])
    return out


def _tendon_bodies(m: mujoco.MjModel, tendon: int) -> set[int]:
    out: set[int] = set()
    wrap = mujoco.mjtWrap
    for w in range(int(m.tendon_adr[tendon]), int(m.tendon_adr[tendon] + m.tendon_num[tendon])):
        kind, obj = int(m.wrap_type[w]), int(m.wrap_objid[w])
        if kind == wrap.mjWRAP_JOINT:
            out.add(int(m.jnt_bodyid[obj]))
        elif kind == wrap.mjWRAP_SITE:
            out.add(int(m.site_bodyid[obj]))
        elif kind in (wrap.mjWRAP_SPHERE, wrap.mjWRAP_CYLINDER):
            out.add(int(m.geom_bodyid[obj]))
    return out


def robot_bodies(m: mujoco.MjModel, roots: Iterable[str] = ()) -> set[int]:
    """Ids of the robot's bodies: whole trees, chosen by ``roots`` or by the actuators.

    Args:
        m: Compiled MuJoCo model.
        roots: Body names; each selects the tree that holds it. Empty: the trees with at least
            one joint that an actuator acts on; when no actuator acts on a jointed tree (a
            passive model), every tree with a joint.

    Returns:
        Body ids (never the world, 0). Mocap bodies and trees without joints are never chosen
        by the actuators.

    Raises:
        UnknownNameError: A name in ``roots`` that is not a body.
    """
    root = tree_roots(m)
    jointed = {int(root[b]) for b in range(1, int(m.nbody)) if m.body_jntnum[b] > 0}
    names = list(roots)
    if names:
        chosen = set()
        for name in names:
            b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, name)
            if b <= 0:
                known = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, i) or "" for i in range(1, m.nbody)]
                raise UnknownNameError("root body", name, [k for k in known if k])
            chosen.add(int(root[b]))
    else:
        chosen = {int(root[b]) for b in actuated_bodies(m) if b > 0} & jointed or jointed
    return {b for b in range(1, int(m.nbody)) if int(root[b]) in chosen}


def scene_bodies(m: mujoco.MjModel, robot: set[int]) -> list[int]:
    """Ids of the bodies that are not the robot (the world excluded), in MuJoCo's order."""
    return [b for b in range(1, int(m.nbody)) if b not in robot]


def describe_body(m: mujoco.MjModel, b: int) -> str:
    """A scene body in words: its name and what it is (mocap, static, free, jointed)."""
    name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b) or f"body #{b}"
    if m.body_mocapid[b] >= 0:
        kind = "mocap"
    elif m.body_jntnum[b] == 0:
        kind = "static" if m.body_weldid[b] == 0 else "welded"
    else:
        first = int(m.body_jntadr[b])
        kinds = {int(m.jnt_type[j]) for j in range(first, first + int(m.body_jntnum[b]))}
        kind = "free" if int(mujoco.mjtJoint.mjJNT_FREE) in kinds else "jointed"
    return f"{name} ({kind}, {float(m.body_mass[b]):.4g} kg)"


class BodiesCom:
    """The centre of mass of a fixed set of bodies, read from any ``MjData`` of the model.

    From ``body_mass`` and ``xipos`` (set by ``mj_kinematics``, and by a step for the step's start):
    the robot's CoM when the bodies are the robot's, whatever else the scene holds
    (``subtree_com[0]`` is the whole plant's). The ids (a slice when contiguous, as the robot's
    are) and the mass weights are gathered once, so a control loop can read it every period.

    Args:
        m: The model.
        bodies: Body ids.

    Attributes:
        mass_kg: The bodies' total mass [kg].
    """

    def __init__(self, m: mujoco.MjModel, bodies: Iterable[int]):
        self._ids = as_slice(sorted(int(b) for b in bodies))
        mass = np.array(m.body_mass[self._ids], dtype=float)
        self.mass_kg = float(mass.sum())
        self._weights = mass / self.mass_kg

    def __call__(self, d: mujoco.MjData) -> np.ndarray:
        """Centre of mass (3,) [m], world frame, at ``d``'s kinematics (a new array)."""
        return self._weights @ d.xipos[self._ids]


def bodies_com(m: mujoco.MjModel, d: mujoco.MjData, bodies: Iterable[int]) -> np.ndarray:
    """Centre of mass (3,) [m], world frame, of ``bodies`` (ids) at ``d``'s kinematics.

    A one-off :class:`BodiesCom`; in a loop, build one once instead.
    """
    return BodiesCom(m, bodies)(d)
