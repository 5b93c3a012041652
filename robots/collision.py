"""Collision pairs of a robot by name, and their distances as MuJoCo measures them.

A pair names two sides, A and B, each a list of names; a name is, in this order of lookup:

* a geom name: that geom;
* a body name: the body's collision geoms (``contype`` or ``conaffinity`` non-zero);
* ``robot``: every collision geom of the robot; ``scene``: every collision geom that is not the
  robot's (the floor, props, mocap targets);
* ``group=N``: every collision geom in MuJoCo geom group N.

A pair expands to every geom pair (a, b), a in A and b in B, except, as mink's
``CollisionAvoidanceLimit`` does (so both IK backends get the same pairs):

* the same body, or bodies welded together (the same ``body_weldid``);
* bodies adjacent in the tree: one's weld is the parent of the other's weld (the world
  included: a floating base's root counts as the floor's neighbour);
* geoms that can never touch: neither ``contype_a & conaffinity_b`` nor ``contype_b & conaffinity_a``;

and, beyond mink, body pairs the model excludes (``<contact><exclude>``). Pairs are unordered:
``(min, max)`` geom ids, deduplicated, in increasing order. ``robot:robot`` is the robot against
itself with adjacent bodies excluded.

Distances come from ``mj_geomDistance(m, d, g1, g2, distmax, fromto)``: the signed distance [m]
(negative: penetration depth), capped at ``distmax``, and the witness points ``fromto`` (p1 on g1,
p2 on g2, world frame). :class:`SelfClearance` asks the other way round, with MuJoCo's collision
detection: which of the robot's geom pairs come within a margin at a configuration.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import mujoco
import numpy as np
import numpy.typing as npt

from mbctl.robots.exceptions import CollisionPairError, UnknownNameError
from mbctl.robots.model_pair import Robot
from mbctl.robots.names import mj_name
from mbctl.robots.plant_kinematics import PlantKinematics

#: Distance cap [m] of a full measurement (the plant check): pairs farther apart read as this.
FAR_M = 10.0

#: The keywords a side of a pair may name besides geoms and bodies.
KEYWORDS = ("robot", "scene", "group=N")


@dataclass(frozen=True)
class CollisionPair:
    """Two sides of names whose geoms are kept apart (see the module docstring for the names).

    Attributes:
        a: Names of side A.
        b: Names of side B.
    """

    a: tuple[str, ...]
    b: tuple[str, ...]

    def __post_init__(self) -> None:
        object.__setattr__(self, "a", tuple(self.a))
        object.__setattr__(self, "b", tuple(self.b))
        if not self.a or not self.b or not all(self.a) or not all(self.b):
            raise CollisionPairError(f"a collision pair needs names on both sides; got {self.a!r}:{self.b!r}")

    @classmethod
    def parse(cls, text: str) -> CollisionPair:
        """``"A1,A2:B1"`` -> ``CollisionPair(("A1", "A2"), ("B1",))``.

        Raises:
            CollisionPairError: Not two non-empty comma-separated lists joined by one colon.
        """
        sides = text.split(":")
        if len(sides) != 2:
            raise CollisionPairError(f"a collision pair is A:B (each side names separated by commas, e.g. "
                                     f"left_elbow_link:right_elbow_link or robot:scene); got {text!r}")
        names = [tuple(n.strip() for n in side.split(",")) for side in sides]
        return cls(names[0], names[1])

    def __str__(self) -> str:
        return f"{','.join(self.a)}:{','.join(self.b)}"


class GeomPairs(NamedTuple):
    """Resolved geom pairs.

    Attributes:
        ids: Geom id pairs (P, 2), ``ids[k, 0] < ids[k, 1]``, rows in increasing order.
        labels: A readable name of each pair, ``"body_a/body_b"`` (see ``geom_label``).
    """

    ids: np.ndarray
    labels: tuple[str, ...]

    def __len__(self) -> int:  # the number of pairs, not of fields
        return int(self.ids.shape[0])


def collision_geoms(m: mujoco.MjModel) -> np.ndarray:
    """Ids of the geoms that can collide at all (``contype`` or ``conaffinity`` non-zero)."""
    return np.flatnonzero((m.geom_contype != 0) | (m.geom_conaffinity != 0))


def body_geoms(m: mujoco.MjModel, body: int) -> tuple[int, ...]:
    """Ids of the geoms of body ``body`` (an id) that can collide (e.g. a foot's soles)."""
    return tuple(int(k) for k in collision_geoms(m) if int(m.geom_bodyid[k]) == body)


def geom_set(robot: Robot, name: str) -> tuple[int, ...]:
    """The geoms one name stands for (see the module docstring for the order of lookup).

    Raises:
        UnknownNameError: Not a geom, body or keyword; the message lists close matches.
    """
    m = robot.mj_model
    g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, name)
    if g >= 0:
        return (g,)
    body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, name)
    if body > 0:
        return body_geoms(m, body)
    colliding = collision_geoms(m)
    in_robot = np.isin(m.geom_bodyid[colliding], robot.robot_body_ids)
    if name == "robot":
        return tuple(int(k) for k in colliding[in_robot])
    if name == "scene":
        return tuple(int(k) for k in colliding[~in_robot])
    if name.startswith("group="):
        try:
            group = int(name.removeprefix("group="))
        except ValueError:
            group = -1
        if 0 <= group <= 5:  # MuJoCo's geom groups are 0..5
            return tuple(int(k) for k in colliding if int(m.geom_group[k]) == group)
    geoms = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, k) for k in range(m.ngeom)]
    bodies = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b) for b in range(1, m.nbody)]
    raise UnknownNameError("collision geom, body or keyword (robot, scene, group=0..5)", name,
                           [*KEYWORDS, *(n for n in bodies if n), *(n for n in geoms if n)])


def _adjacent(m: mujoco.MjModel, b1: int, b2: int) -> bool:
    """Same weld, or one weld the parent of the other (mink's rules)."""
    w1, w2 = int(m.body_weldid[b1]), int(m.body_weldid[b2])
    if w1 == w2:
        return True
    p1, p2 = int(m.body_weldid[m.body_parentid[w1]]), int(m.body_weldid[m.body_parentid[w2]])
    return w1 == p2 or w2 == p1


def _excluded(m: mujoco.MjModel) -> set[tuple[int, int]]:
    """Body pairs in ``<contact><exclude>`` (MuJoCo stores ``min << 16 | max``)."""
    return {(int(s) >> 16, int(s) & 0xFFFF) for s in m.exclude_signature}


def _can_touch(m: mujoco.MjModel, g1: int, g2: int) -> bool:
    contype, conaffinity = m.geom_contype, m.geom_conaffinity
    return bool(contype[g1] & conaffinity[g2]) or bool(contype[g2] & conaffinity[g1])


def resolve_pairs(robot: Robot, pairs: Sequence[CollisionPair]) -> GeomPairs:
    """Expand named pairs into geom id pairs (the rules in the module docstring).

    Raises:
        UnknownNameError: A name that is not a geom, body or keyword.
        CollisionPairError: A named pair that leaves no geom pair (the message says why).
    """
    m = robot.mj_model
    excluded = _excluded(m)
    out: set[tuple[int, int]] = set()
    for pair in pairs:
        side_a = {g for name in pair.a for g in geom_set(robot, name)}
        side_b = {g for name in pair.b for g in geom_set(robot, name)}
        found = set()
        for g1 in side_a:
            for g2 in side_b:
                b1, b2 = int(m.geom_bodyid[g1]), int(m.geom_bodyid[g2])
                if (g1 == g2 or _adjacent(m, b1, b2) or not _can_touch(m, g1, g2)
                        or (min(b1, b2), max(b1, b2)) in excluded):
                    continue
                found.add((min(g1, g2), max(g1, g2)))
        if not found:
            raise CollisionPairError(
                f"collision pair {pair} leaves no geom pair: its sides have {len(side_a)} and {len(side_b)} "
                "collision geoms, and every pair between them is on one body, on adjacent bodies, excluded "
                "by the model, or can never touch (contype/conaffinity)")
        out |= found
    ids = np.array(sorted(out), dtype=int).reshape(-1, 2)
    return GeomPairs(ids, tuple(f"{geom_label(m, a)}/{geom_label(m, b)}" for a, b in ids))


def geom_label(m: mujoco.MjModel, g: int) -> str:
    """A geom's name, else its body's (``body[k]`` when the body has several collision geoms)."""
    name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g)
    if name:
        return name
    b = int(m.geom_bodyid[g])
    body = mj_name(m, mujoco.mjtObj.mjOBJ_BODY, b)
    same = [k for k in collision_geoms(m) if int(m.geom_bodyid[k]) == b]
    return body if len(same) <= 1 or g not in same else f"{body}[{same.index(g)}]"


def pair_distances(m: mujoco.MjModel, d: mujoco.MjData, ids: np.ndarray, distmax: float = FAR_M,
                   fromto: np.ndarray | None = None) -> np.ndarray:
    """Signed distance [m] of each pair (P,) at ``d``'s kinematics, capped at ``distmax``.

    Args:
        m: The MuJoCo model.
        d: Data after ``mj_kinematics`` (geom poses).
        ids: Geom id pairs (P, 2).
        distmax: Cap [m]: pairs farther apart read as ``distmax``.
        fromto: Optional (P, 6) output: witness points p1 (on the first geom), p2 (world) [m].
    """
    out = np.empty(len(ids))
    seg = np.empty(6)
    for k, (g1, g2) in enumerate(ids):
        out[k] = mujoco.mj_geomDistance(m, d, int(g1), int(g2), distmax, seg)
        if fromto is not None:
            fromto[k] = seg
    return out


class ClosestPair(NamedTuple):
    """The closest pair at one configuration.

    Attributes:
        distance_m: Its signed distance [m] (negative: penetration), at most :data:`FAR_M`.
        pair: Its label (:attr:`GeomPairs.labels`).
    """

    distance_m: float
    pair: str


def closest_pairs(robot: Robot, qs: npt.ArrayLike, pairs: GeomPairs) -> list[ClosestPair]:
    """The closest pair at each configuration, measured by MuJoCo on a scratch ``MjData``.

    Args:
        robot: The model pair (its ``mj_model`` is read, never stepped).
        qs: Configurations (N, nq), Pinocchio convention.
        pairs: The pairs to measure (at least one).
    """
    m = robot.mj_model
    kinematics = PlantKinematics(robot=robot)
    out = []
    for q in np.atleast_2d(np.asarray(qs, dtype=float)):
        dist = pair_distances(m, kinematics.at(q), pairs.ids)
        k = int(np.argmin(dist))
        out.append(ClosestPair(float(dist[k]), pairs.labels[k]))
    return out


class SelfClearance:
    """Which pairs of the robot's own geoms come within a margin of each other at a configuration.

    MuJoCo's collision detection (``mj_collision``, with the model's contype/conaffinity, parent-
    child and exclude filters) on a copy of the model whose geom margins are at least
    ``margin_m``; contacts with geoms that are not the robot's (the floor, props) do not count,
    nor do pairs already that close at ``q_start`` (neighbouring links).

    Args:
        robot: The model pair (its model is copied, never stepped).
        margin_m: Clearance [m] a pair must keep.
        q_start: The start configuration (nq,), Pinocchio convention.
    """

    def __init__(self, robot: Robot, margin_m: float, q_start: npt.ArrayLike):
        m = copy.copy(robot.mj_model)
        m.geom_margin[:] = np.maximum(m.geom_margin, margin_m)
        self._kinematics = PlantKinematics(m, robot)
        self._robot_geoms = set(np.flatnonzero(np.isin(m.geom_bodyid, robot.robot_body_ids)).tolist())
        self.neighbours: frozenset[tuple[int, int]] = frozenset()
        self.neighbours = frozenset(self.pairs(q_start))

    def pairs(self, q: npt.ArrayLike) -> set[tuple[int, int]]:
        """Geom id pairs (min, max) of the robot within the margin at ``q`` (nq,), neighbours left out."""
        self._kinematics.at(q)
        d = self._kinematics.collide()
        out = set()
        for c in d.contact[: d.ncon]:
            g1, g2 = int(c.geom1), int(c.geom2)
            if g1 in self._robot_geoms and g2 in self._robot_geoms:
                out.add((min(g1, g2), max(g1, g2)))
        return out - self.neighbours

    def touches(self, q: npt.ArrayLike) -> bool:
        """Whether two of the robot's geoms (not neighbours at the start) come within the margin at ``q``."""
        return bool(self.pairs(q))
