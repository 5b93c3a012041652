"""Contact forces measured in the plant: what MuJoCo applied to a set of geoms (world frame W).

``mj_contactForce`` gives each contact's force in its contact frame (normal first); the frame's
rows are its axes in W and its normal points from geom1 to geom2, and the force acts on geom2 (the
opposite on geom1). These helpers sum, per group of geoms (a foot), the force on the group in W,
the normal (z) and tangential parts, and the centre of pressure on the ground.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import TypeVar

import mujoco
import numpy as np

_K = TypeVar("_K")


@dataclass(frozen=True)
class MeasuredContact:
    """The plant's contact force on one group of geoms.

    Attributes:
        force_W: Sum of the contact forces on the group (3,) [N] in W.
        cop_W: Centre of pressure (3,) [m] in W (force-weighted contact positions; NaN without
            normal force).
        n_contacts: Number of active contacts.
    """

    force_W: np.ndarray
    cop_W: np.ndarray
    n_contacts: int

    @property
    def normal_n(self) -> float:
        """Normal (world z) force [N]."""
        return float(self.force_W[2])

    @property
    def tangential_n(self) -> float:
        """Tangential (world x-y) force magnitude [N]."""
        return float(np.hypot(self.force_W[0], self.force_W[1]))


def measure_contacts(model: mujoco.MjModel, data: mujoco.MjData,
                     groups: Mapping[str, Iterable[int]]) -> dict[str, MeasuredContact]:
    """Force, CoP and contact count on each group of geom ids, from ``data``'s current contacts.

    Read it right after ``mj_step`` for the forces applied during that step (the contacts and
    their forces are those of the step's forward pass).
    """
    force = {name: np.zeros(3) for name in groups}
    moment_xy = {name: np.zeros(2) for name in groups}
    count = dict.fromkeys(groups, 0)
    for group, f_W, p_W in _forces_on(model, data, groups.items()):
        force[group] += f_W
        moment_xy[group] += f_W[2] * p_W[:2]
        count[group] += 1
    out = {}
    for name in groups:
        fz = force[name][2]
        cop = np.full(3, np.nan)
        if fz > 1e-9:
            cop = np.array([*(moment_xy[name] / fz), 0.0])
        out[name] = MeasuredContact(force[name], cop, count[name])
    return out


def touching(model: mujoco.MjModel, data: mujoco.MjData, body_geoms: Iterable[int],
             allowed: Iterable[int]) -> list[str]:
    """Names of bodies (other than ``allowed`` geoms) touching any of ``body_geoms`` (e.g. the floor)."""
    targets, ok = set(int(g) for g in body_geoms), set(int(g) for g in allowed)
    names = []
    for i in range(data.ncon):
        con = data.contact[i]
        g1, g2 = int(con.geom1), int(con.geom2)
        for a, b in ((g1, g2), (g2, g1)):
            if a in targets and b not in ok and b not in targets:
                names.append(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, model.geom_bodyid[b])
                             or f"body {model.geom_bodyid[b]}")
    return sorted(set(names))


def contact_wrenches(model: mujoco.MjModel, data: mujoco.MjData, groups: Sequence[Iterable[int]],
                     points_W: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Whether each group of geoms touches, and the wrench the contacts apply to it (a force sensor).

    Args:
        model: The plant's model.
        data: Its data, right after ``mj_step`` (the contacts of the step just taken).
        groups: Geom ids per group (e.g. a foot's collision geoms), c groups.
        points_W: Reference point of each group (c, 3) [m] in W (e.g. the foot body's origin).

    Returns:
        touching (c,) bool (at least one contact), and wrenches (c, 6): force [N] then moment
        about the group's point [N m], world axes W.
    """
    n = len(points_W)
    touching = np.zeros(n, dtype=bool)
    wrench = np.zeros((n, 6))
    for group, f_W, p_W in _forces_on(model, data, enumerate(groups)):
        touching[group] = True
        wrench[group, :3] += f_W
        wrench[group, 3:] += np.cross(p_W - points_W[group], f_W)
    return touching, wrench


def _forces_on(model: mujoco.MjModel, data: mujoco.MjData, groups: Iterable[tuple[_K, Iterable[int]]]
               ) -> Iterator[tuple[_K, np.ndarray, np.ndarray]]:
    """(group, force on it f_W (3,) [N], contact point p_W (3,) [m]) for every contact on a group's geom."""
    owner = {int(g): key for key, geoms in groups for g in geoms}
    f6 = np.zeros(6)
    for i in range(data.ncon):
        con = data.contact[i]
        for geom, sign in ((con.geom2, 1.0), (con.geom1, -1.0)):
            group = owner.get(int(geom))
            if group is None:
                continue
            mujoco.mj_contactForce(model, data, i, f6)
            yield group, sign * (con.frame.reshape(3, 3).T @ f6[:3]), np.array(con.pos)


def contacts_elsewhere(model: mujoco.MjModel, data: mujoco.MjData, bodies: Iterable[int],
                       allowed: Iterable[int]) -> int:
    """Contacts that touch any of ``bodies`` through a geom not in ``allowed``.

    Self-collisions, a hand on a table: forces a model of the ``allowed`` contacts does not explain.
    """
    mine, ok = {int(b) for b in bodies}, {int(g) for g in allowed}
    count = 0
    for i in range(data.ncon):
        con = data.contact[i]
        for geom in (int(con.geom1), int(con.geom2)):
            if geom not in ok and int(model.geom_bodyid[geom]) in mine:
                count += 1
                break
    return count
