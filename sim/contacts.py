"""Contact forces measured in the plant: what MuJoCo applied to a set of geoms (world frame W).

``mj_contactForce`` gives each contact's force in its contact frame (normal first); the frame's
rows are its axes in W and its normal points from geom1 to geom2, and the force acts on geom2 (the
opposite on geom1). A :class:`ContactSensor` sums, per group of geoms (a foot), the force on the
group in W, the normal (z) and tangential parts, and the centre of pressure on the ground; a
:class:`FloorContacts` names the bodies touching the floor. Both look their geoms up in arrays built
once, so a control loop can read them every period for the price of ``mj_contactForce`` on the
contacts that concern them.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import mujoco
import numpy as np


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


class ContactSensor:
    """Measures the contact force on named groups of geoms from an ``MjData``'s current contacts.

    Read it right after ``mj_step`` for the forces applied during that step (the contacts and
    their forces are those of the step's forward pass).

    Args:
        model: The compiled model.
        groups: Geom ids per group name (a geom in two groups counts for the last).
    """

    def __init__(self, model: mujoco.MjModel, groups: Mapping[str, Iterable[int]]):
        self.model = model
        self.names = tuple(groups)
        self._owner = np.full(model.ngeom, -1, dtype=int)  # group index of each geom, -1: none
        for k, geoms in enumerate(groups.values()):
            self._owner[np.asarray(list(geoms), dtype=int)] = k
        self._f6 = np.zeros(6)

    def measure(self, data: mujoco.MjData) -> dict[str, MeasuredContact]:
        """Force, CoP and contact count on each group."""
        n_groups = len(self.names)
        force = np.zeros((n_groups, 3))
        moment_xy = np.zeros((n_groups, 2))
        count = np.zeros(n_groups, dtype=int)
        ncon = data.ncon
        if ncon:
            contact = data.contact
            owner = self._owner[contact.geom[:ncon]]  # (ncon, 2): group of geom1, geom2
            f6 = self._f6
            for i in np.flatnonzero((owner >= 0).any(axis=1)).tolist():
                mujoco.mj_contactForce(self.model, data, i, f6)
                f_W = contact.frame[i].reshape(3, 3).T @ f6[:3]  # on geom2, in W
                for side, sign in ((1, 1.0), (0, -1.0)):
                    k = owner[i, side]
                    if k >= 0:
                        force[k] += sign * f_W
                        moment_xy[k] += sign * f_W[2] * contact.pos[i, :2]
                        count[k] += 1
        out = {}
        for k, name in enumerate(self.names):
            fz = force[k, 2]
            cop = np.array([*(moment_xy[k] / fz), 0.0]) if fz > 1e-9 else np.full(3, np.nan)
            out[name] = MeasuredContact(force[k], cop, int(count[k]))
        return out


class FloorContacts:
    """Names the bodies that touch a set of geoms (e.g. the floor), other than allowed geoms.

    Args:
        model: The compiled model.
        floor_geoms: The geoms touched (e.g. the world body's).
        allowed: Geoms whose touches do not count (e.g. the feet).
        bodies: Only bodies among these ids are reported (default: every body).
    """

    def __init__(self, model: mujoco.MjModel, floor_geoms: Iterable[int], allowed: Iterable[int] = (),
                 bodies: Iterable[int] | None = None):
        self._floor = np.zeros(model.ngeom, dtype=bool)
        self._floor[np.asarray(list(floor_geoms), dtype=int)] = True
        self._counts = np.ones(model.ngeom, dtype=bool)
        self._counts[np.asarray(list(allowed), dtype=int)] = False
        self._counts &= ~self._floor
        if bodies is not None:
            self._counts &= np.isin(model.geom_bodyid, np.asarray(list(bodies), dtype=int))
        self._body_name = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, int(b)) or f"body {int(b)}"
                           for b in model.geom_bodyid]

    def bodies(self, data: mujoco.MjData) -> list[str]:
        """Sorted names of the bodies touching the floor geoms now."""
        ncon = data.ncon
        if not ncon:
            return []
        geom = data.contact.geom[:ncon]
        a, b = geom[:, 0], geom[:, 1]
        hits = np.concatenate([b[self._floor[a] & self._counts[b]], a[self._floor[b] & self._counts[a]]])
        return sorted({self._body_name[g] for g in hits.tolist()})


def measure_contacts(model: mujoco.MjModel, data: mujoco.MjData,
                     groups: Mapping[str, Iterable[int]]) -> dict[str, MeasuredContact]:
    """Force, CoP and contact count on each group of geom ids (a one-off :class:`ContactSensor`)."""
    return ContactSensor(model, groups).measure(data)


def touching(model: mujoco.MjModel, data: mujoco.MjData, body_geoms: Iterable[int],
             allowed: Iterable[int]) -> list[str]:
    """Names of bodies (other than ``allowed`` geoms) touching any of ``body_geoms`` (e.g. the floor)."""
    return FloorContacts(model, body_geoms, allowed).bodies(data)
