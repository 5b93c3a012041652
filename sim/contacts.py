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

import math
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import TypeVar

import mujoco
import numpy as np

from mbctl.robots.edits import CONTACT_SENSOR_DATA, NETFORCE, contact_data_bit

_K = TypeVar("_K")
_SENSOR_OFF = int(mujoco.mjtDisableBit.mjDSBL_SENSOR)


def sums_block(nets: np.ndarray) -> np.ndarray:
    """:meth:`ContactSensor.sums` of many periods at once: (b, 10 G) nets -> (b, G, 6) sums.

    Each row is a period's :meth:`ContactSensor.net` (G groups); each group's sums are ``[fx, fy,
    fz, fz x, fz y, n]``: the force on the group [N] in W, fz times its centre of pressure [N m] and
    the number of contacts (a float here).
    """
    a = nets.reshape(len(nets), -1, 10)
    out = np.empty((*a.shape[:2], 6))
    fz = a[..., 3]
    out[..., :3] = -a[..., 1:4]  # what the group exerts, turned into what acts on it
    # fz * CoP = fz p + (horizontal moment about p) x z
    out[..., 3] = a[..., 5] - fz * a[..., 7]
    out[..., 4] = -a[..., 4] - fz * a[..., 8]
    out[..., 5] = a[..., 0]
    return out


def sensors_on(options: mujoco.MjOption) -> bool:
    """Whether MuJoCo computes its sensors now (``options``: a model's ``opt``, read live)."""
    return not options.disableflags & _SENSOR_OFF
#: The sizes of a contact sensor's data fields, in MuJoCo's order (``mjtConDataField``).
_FIELD_SIZES = (1, 3, 3, 1, 3, 3, 3)


@dataclass(frozen=True)
class MeasuredContact:
    """The plant's contact force on one group of geoms.

    Attributes:
        force_W: Sum of the contact forces on the group (3,) [N] in W.
        cop_W: Centre of pressure (3,) [m] in W (see :class:`ContactSensor`; NaN without
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

    Where a group is the colliding geoms of one body and the model has that body's net-force
    contact sensor (:func:`mbctl.robots.edits.add_contact_sensors`), MuJoCo has summed the group's
    contacts during the step (in C) and the sums are read from ``sensordata``; otherwise a loop
    over the contacts (``mj_contactForce``) sums them. Both give the same numbers (to rounding).

    The centre of pressure is where the contacts' moment has no horizontal part, on the horizontal
    plane through their force-weighted centroid (the |f|-weighted contact positions, the point
    MuJoCo's net-force sensor reports): the z-force-weighted contact positions when the contacts
    lie in one horizontal plane (a flat floor); off it, by about the contacts' height spread times
    their tangential-to-normal force ratio (a few micrometres for a G1 foot on the floor).

    Args:
        model: The compiled model.
        groups: Geom ids per group name (a geom in two groups counts for the last).
    """

    def __init__(self, model: mujoco.MjModel, groups: Mapping[str, Iterable[int]]):
        self.model = model
        self._opt = model.opt  # a live view of the model's options, bound once (read every period)
        self.names = tuple(groups)
        self._owner = np.full(model.ngeom, -1, dtype=int)  # group index of each geom, -1: none
        for k, geoms in enumerate(groups.values()):
            self._owner[np.asarray(list(geoms), dtype=int)] = k
        self._owner_list = self._owner.tolist()
        self._f6 = np.zeros(6)
        #: The sensordata indices of each group's net-force sensor (10 a group), or None: the loop.
        self.sensor_index = _net_force_sensors(model, self._owner, len(self.names))

    @property
    def from_sensors(self) -> bool:
        """Whether the sums come from MuJoCo's contact sensors (now: sensors not disabled)."""
        return self.sensor_index is not None and sensors_on(self._opt)

    def net(self, data: mujoco.MjData, geoms: list[list[int]] | None = None) -> list[float]:
        """Each group's net contact, 10 plain numbers a group in ``names`` order (MuJoCo's sensor layout).

        Per group: the number of contacts; the force (3,) [N] and the moment (3,) [N m] about the
        contacts' force-weighted centroid that the group exerts on what it touches (minus those on
        it), world axes; that centroid (3,) [m]. From MuJoCo's net-force sensors when the model has
        them (one read), else summed over the contacts. :meth:`sums_from` turns it into sums.

        Args:
            data: Right after ``mj_step``.
            geoms: ``data.contact.geom.tolist()`` if the caller read it already (one read per period).
        """
        if self.from_sensors:
            return data.sensordata.take(self.sensor_index).tolist()
        return self.loop_net(data, geoms)

    def loop_net(self, data: mujoco.MjData, geoms: list[list[int]] | None = None) -> list[float]:
        """:meth:`net` summed over the contacts (``mj_contactForce`` on each of a group), sensors or not."""
        acc = [[0.0] * 10 + [0] for _ in self.names]  # F (3), |f|, |f| p (3), p x f (3), count
        if data.ncon:
            self._accumulate(data, acc, data.contact.geom.tolist() if geoms is None else geoms)
        out: list[float] = []
        for fx, fy, fz, w, wx, wy, wz, mx, my, mz, n in acc:
            px, py, pz = (wx / w, wy / w, wz / w) if w > 0.0 else (0.0, 0.0, 0.0)
            # the moment about the centroid p: M_p = M_0 - p x F
            out += (n, -fx, -fy, -fz, -(mx - (py * fz - pz * fy)), -(my - (pz * fx - px * fz)),
                    -(mz - (px * fy - py * fx)), px, py, pz)
        return out

    def sums_from(self, net: Sequence[float]) -> list[list[float]]:
        """:meth:`sums` from a period's :meth:`net` (read then, converted now; a list or an array).

        :func:`sums_block`'s formula, on plain floats: one period's costs ~1 us so, ~9 through numpy.
        """
        if isinstance(net, np.ndarray):
            net = net.tolist()
        out = []
        for k in range(0, len(net), 10):
            n, fx, fy, fz, nx, ny, _, px, py, _ = net[k:k + 10]
            out.append([-fx, -fy, -fz, ny - fz * px, -nx - fz * py, int(n)])
        return out

    def sums(self, data: mujoco.MjData, geoms: list[list[int]] | None = None) -> list[list[float]]:
        """Per group, in ``names`` order: ``[fx, fy, fz, fz x, fz y, n]``, plain Python numbers.

        The force on the group (3,) [N] in W, fz times the centre of pressure's x, y [N m] (the CoP
        is their ratio to fz) and the number of active contacts: what :meth:`measure` reports, without
        its arrays and objects.

        Args:
            data: Right after ``mj_step``.
            geoms: ``data.contact.geom.tolist()`` if the caller read it already (one read per period).
        """
        return self.sums_from(self.net(data, geoms))

    def _accumulate(self, data: mujoco.MjData, acc: list[list], geoms: list[list[int]]) -> None:
        contact = data.contact
        owner, f6, model, contact_force = self._owner_list, self._f6, self.model, mujoco.mj_contactForce
        # each array's rows to Python once, when a contact concerns a group
        frames: list[list[float]] = []
        positions: list[list[float]] = []
        # plain Python floats: with a handful of contacts, per-contact arithmetic on floats costs less
        # than numpy (~1 us per call on these small arrays)
        for i, (g1, g2) in enumerate(geoms):
            k1, k2 = owner[g1], owner[g2]
            if k1 < 0 and k2 < 0:
                continue
            if not frames:
                frames, positions = contact.frame.tolist(), contact.pos.tolist()
            contact_force(model, data, i, f6)
            fn, t1, t2 = f6[:3].tolist()
            r = frames[i]  # rows: the contact frame's axes in W; f_W = frame^T f
            fx = r[0] * fn + r[3] * t1 + r[6] * t2
            fy = r[1] * fn + r[4] * t1 + r[7] * t2
            fz = r[2] * fn + r[5] * t1 + r[8] * t2
            px, py, pz = positions[i]
            w = math.sqrt(fn * fn + t1 * t1 + t2 * t2)
            mx, my, mz = py * fz - pz * fy, pz * fx - px * fz, px * fy - py * fx  # p x f
            # the force acts on geom2, the opposite on geom1
            for k, sign in ((k2, 1.0), (k1, -1.0)):
                if k >= 0:
                    a = acc[k]
                    a[0] += sign * fx
                    a[1] += sign * fy
                    a[2] += sign * fz
                    a[3] += w
                    a[4] += w * px
                    a[5] += w * py
                    a[6] += w * pz
                    a[7] += sign * mx
                    a[8] += sign * my
                    a[9] += sign * mz
                    a[10] += 1

    def measure(self, data: mujoco.MjData) -> dict[str, MeasuredContact]:
        """Force, CoP and contact count on each group."""
        return measured(self.names, self.sums(data))


def _net_force_sensors(model: mujoco.MjModel, owner: np.ndarray, n_groups: int) -> np.ndarray | None:
    """The sensordata indices (10 a group) of each group's net-force contact sensor, or None.

    A group qualifies when it holds every geom of one body that can collide (contype, conaffinity
    or an explicit pair) and the model has a contact sensor on that body alone (``body1``, any
    other side, no cutoff) with ``reduce="netforce"`` and at least the fields found, force, torque
    and pos. None unless every group qualifies.
    """
    sensors = np.flatnonzero(model.sensor_type == int(mujoco.mjtSensor.mjSENS_CONTACT))
    if not n_groups or not sensors.size:
        return None
    paired = set(model.pair_geom1.tolist()) | set(model.pair_geom2.tolist())
    collides = [bool(model.geom_contype[g] or model.geom_conaffinity[g]) or g in paired
                for g in range(model.ngeom)]
    bits = [contact_data_bit(f) for f in CONTACT_SENSOR_DATA]
    body_type = int(mujoco.mjtObj.mjOBJ_BODY)
    index = []
    for k in range(n_groups):
        geoms = np.flatnonzero(owner == k)
        bodies = set(model.geom_bodyid[geoms].tolist())
        if len(bodies) != 1:
            return None
        body = bodies.pop()
        others = [g for g in np.flatnonzero(model.geom_bodyid == body) if owner[g] != k]
        if any(collides[g] for g in others):
            return None
        found = None
        for s in sensors:
            fields, reduce = int(model.sensor_intprm[s, 0]), int(model.sensor_intprm[s, 1])
            if (int(model.sensor_objtype[s]) == body_type and int(model.sensor_objid[s]) == body
                    and int(model.sensor_refid[s]) < 0 and reduce == NETFORCE and model.sensor_cutoff[s] == 0
                    and all(fields >> b & 1 for b in bits)):
                found = s
                break
        if found is None:
            return None
        fields = int(model.sensor_intprm[found, 0])
        offsets = np.cumsum([0, *(size if fields >> b & 1 else 0 for b, size in enumerate(_FIELD_SIZES))])
        adr = int(model.sensor_adr[found])
        found_at, force_at, torque_at, pos_at = (adr + int(offsets[b]) for b in bits)
        index += [found_at, *range(force_at, force_at + 3), *range(torque_at, torque_at + 3),
                  *range(pos_at, pos_at + 3)]
    return np.array(index, dtype=int)


def measured(names: Sequence[str], sums: Sequence[Sequence[float]]) -> dict[str, MeasuredContact]:
    """A :class:`MeasuredContact` per group from :meth:`ContactSensor.sums` (CoP NaN without normal force)."""
    out = {}
    for name, (fx, fy, fz, mx, my, n) in zip(names, sums, strict=True):
        cop = np.array([mx / fz, my / fz, 0.0]) if fz > 1e-9 else np.full(3, np.nan)
        out[name] = MeasuredContact(np.array([fx, fy, fz]), cop, int(n))
    return out


class FloorSensors:
    """The robot's bodies on the floor from MuJoCo's counts (:func:`~mbctl.robots.edits.add_floor_sensors`).

    Found in the model by what each sensor counts (its object, the world body on its other side,
    the ``found`` field), not by name: the robot's whole tree's contacts with the floor, and some
    bodies' own. ``index`` gives where those counts are in ``sensordata``: the robot's, then the
    bodies' (``names``, sorted); :meth:`bodies` answers from them.

    Args:
        model: The compiled model.
        root: The robot's one root body (its tree is the robot).
        bodies: The robot's bodies (ids) whose own counts may be read.

    Attributes:
        index: Indices into ``sensordata`` (1 + k,), or None when the model lacks the robot's count
            or every body's.
        names: The bodies counted (k,), sorted by name.
    """

    def __init__(self, model: mujoco.MjModel, root: int, bodies: Iterable[int]):
        found_bit = contact_data_bit("found")
        counts: dict[int, int] = {}  # sensor object (-1 - root for the tree) -> its count's address
        for s in np.flatnonzero(model.sensor_type == int(mujoco.mjtSensor.mjSENS_CONTACT)).tolist():
            if not (int(model.sensor_intprm[s, 0]) >> found_bit & 1 and int(model.sensor_reftype[s])
                    == int(mujoco.mjtObj.mjOBJ_BODY) and int(model.sensor_refid[s]) == 0
                    and model.sensor_cutoff[s] == 0):
                continue  # found is the first field of a slot: at the sensor's address
            obj, kind = int(model.sensor_objid[s]), int(model.sensor_objtype[s])
            if kind == int(mujoco.mjtObj.mjOBJ_XBODY) and obj == root:
                counts[-1 - root] = int(model.sensor_adr[s])
            elif kind == int(mujoco.mjtObj.mjOBJ_BODY):
                counts[obj] = int(model.sensor_adr[s])
        named = sorted((mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) or f"body {b}", b)
                       for b in bodies if b in counts)
        self.names: tuple[str, ...] = tuple(n for n, _ in named)
        self.index = (np.array([counts[-1 - root], *(counts[b] for _, b in named)], dtype=int)
                      if -1 - root in counts and named else None)

    def bodies(self, counts: Sequence[float]) -> tuple[str, ...] | None:
        """The bodies on the floor (sorted), from the counts read at ``index``; None if others touch it too.

        Each contact between the robot and the floor is counted once by the robot's sensor and once
        by its body's; where the bodies' counts add up to the robot's, no other body has one.
        """
        if counts[0] != sum(counts[1:]):
            return None
        return tuple(name for name, n in zip(self.names, counts[1:], strict=True) if n)


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
        self._floor_list, self._counts_list = self._floor.tolist(), self._counts.tolist()
        self._body_name = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, int(b)) or f"body {int(b)}"
                           for b in model.geom_bodyid]

    def bodies(self, data: mujoco.MjData, geoms: list[list[int]] | None = None) -> list[str]:
        """Sorted names of the bodies touching the floor geoms now.

        Args:
            data: The data.
            geoms: ``data.contact.geom.tolist()`` if the caller read it already (one read per period).
        """
        if geoms is None:
            if not data.ncon:
                return []
            geoms = data.contact.geom.tolist()
        # plain Python over a handful of contacts: cheaper than eight numpy temporaries
        floor, counts, name = self._floor_list, self._counts_list, self._body_name
        hits = set()
        for a, b in geoms:
            if floor[a] and counts[b]:
                hits.add(name[b])
            if floor[b] and counts[a]:
                hits.add(name[a])
        return sorted(hits)


def measure_contacts(model: mujoco.MjModel, data: mujoco.MjData,
                     groups: Mapping[str, Iterable[int]]) -> dict[str, MeasuredContact]:
    """Force, CoP and contact count on each group of geom ids (a one-off :class:`ContactSensor`)."""
    return ContactSensor(model, groups).measure(data)


def touching(model: mujoco.MjModel, data: mujoco.MjData, body_geoms: Iterable[int],
             allowed: Iterable[int]) -> list[str]:
    """Names of bodies (other than ``allowed`` geoms) touching any of ``body_geoms`` (e.g. the floor)."""
    return FloorContacts(model, body_geoms, allowed).bodies(data)


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
