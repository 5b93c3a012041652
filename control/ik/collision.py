"""Collision avoidance as an IK limit: a velocity damper on the distance of geom pairs.

For each pair (geoms 1 and 2, :mod:`mbctl.robots.collision`) closer than the detection distance,
MuJoCo gives the signed distance d and the witness points p1, p2 (``mj_geomDistance`` on a scratch
``MjData`` at the state's q); the separating direction is ``n = s (p2 - p1)/|p2 - p1|`` with
``s = sign(d)`` (MuJoCo's segment points inwards when the geoms overlap). The distance's rate
along the step is ``d' = n^T (J_p2 - J_p1) dq`` with ``J_p`` the world-frame Jacobian of the
point p moving with its body, from the model pair's Pinocchio Jacobians::

    J_p dq = v_O + w x p  =>  n^T J_p = [n; p x n]^T J_B

with ``J_B = [v_O; w]`` the WORLD-frame Jacobian of the body's joint (``data.J`` after the
state's update, as ``pin.computeJointJacobians`` leaves it, restricted to the joints that move
the body). Since ``p2 - p1`` is along n, ``p2 x n = p1 x n``: one row ``[n; p1 x n]^T data.J``
serves both points, with the dofs that move only geom 1 counted +1 and only geom 2 counted -1
(the ones moving both cancel). The limit is the
velocity damper (Kanoun et al.; mink's ``CollisionAvoidanceLimit``)::

    -d'(dq) <= gain (d - d_min)    if d > d_min,    -d'(dq) <= 0  otherwise

so a pair approaches its minimum distance geometrically and a pair already inside it does not
close further. One difference from mink, which bounds ``-d'`` by ``gain (d - d_min) / dt``: the
QP's variable is the step ``dq``, so the bound on the step's approach is not divided by ``dt``
(the two agree at ``dt = 1 s``, the whole-body IK's default); with mink's bound a step of
``dt = 0.01 s`` may close 100 times the gap.

A broad phase skips pairs whose bounding spheres (``geom_rbound``, 0 for planes: never skipped)
are farther apart than the detection distance, before any ``mj_geomDistance``.

The damper is a linearisation, and whole-body IK steps are large (centimetres, tenths of a radian),
so a pair may close faster than its row predicts, or come from beyond the detection distance in
one step. :meth:`CollisionAvoidanceLimit.guard_step` therefore measures the pairs at the step's end
(MuJoCo again) and halves the step while any pair ends below the minimum distance and closer than
it started (at most :data:`MAX_HALVINGS` times; then the step is zero and the solve stalls where
it is, collision-free). The measurement is kept for the next step's rows, so a step that needs no
halving costs no extra distance query. mink has no such guard.
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np
import pinocchio as pin

from mbctl.control.exceptions import IKSetupError
from mbctl.control.ik.limits import Constraint, Limit
from mbctl.control.tasks.state import TaskState
from mbctl.robots.collision import CollisionPair, GeomPairs, resolve_pairs
from mbctl.robots.model_pair import Robot
from mbctl.robots.names import mj_name

#: How many times :meth:`CollisionAvoidanceLimit.guard_step` may halve a step.
MAX_HALVINGS = 6


def _levi_civita() -> np.ndarray:
    """The Levi-Civita symbol as a (3, 9) matrix: ``a x b = eps @ vec(a b^T)`` (row-major ``vec``)."""
    eps = np.zeros((3, 3, 3))
    for i, j, k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        eps[i, j, k], eps[i, k, j] = 1.0, -1.0
    out = eps.reshape(3, 9)
    out.setflags(write=False)
    return out


#: ``(a x b)_i = sum_jk eps_ijk a_j b_k``, a product with the outer product ``a b^T`` flattened.
_LEVI_CIVITA = _levi_civita()

#: ``[p2 - p1; p1] = _SPLIT @ [p1; p2]``: a pair's witness segment (MuJoCo's ``fromto``) as the
#: segment's vector and its first point (entries 0 and +-1: exact).
_SPLIT = np.block([[-np.eye(3), np.eye(3)], [np.eye(3), np.zeros((3, 3))]])
_SPLIT.setflags(write=False)

_ONES3 = np.ones(3)

#: Above this many entries (pairs x distinct geoms) the broad phase gathers the geoms' centres
#: instead of one product with the pairs' incidence matrix.
INCIDENCE_MAX = 1 << 14


def body_dof_masks(robot: Robot) -> np.ndarray:
    """(nbody, nv) 0/1: the tangent dofs that move each MuJoCo body (zero rows for scene bodies).

    Raises:
        IKSetupError: A robot body that is not a Pinocchio body frame of the same name.
    """
    m, model = robot.mj_model, robot.pin_model
    masks = np.zeros((m.nbody, model.nv))
    for b in robot.robot_body_ids:
        name = mj_name(m, mujoco.mjtObj.mjOBJ_BODY, b)
        if not model.existFrame(name, pin.FrameType.BODY):
            raise IKSetupError(f"MuJoCo body {name!r} has no Pinocchio BODY frame of that name; "
                               "collision avoidance needs the model pair's body frames")
        joint = model.frames[model.getFrameId(name, pin.FrameType.BODY)].parentJoint
        for j in model.supports[joint]:
            if j > 0:
                start = model.joints[j].idx_v
                masks[b, start:start + model.joints[j].nv] = 1.0
    return masks


class CollisionAvoidanceLimit(Limit):
    """Keep geom pairs at least ``min_distance_m`` apart: ``-d'(dq) <= gain max(d - d_min, 0)``.

    Attributes:
        robot: The model pair (MuJoCo measures, Pinocchio differentiates).
        pairs: The geom pairs.
        min_distance_m: Minimum distance d_min [m] (negative: allowed penetration).
        detection_distance_m: Pairs farther apart than this [m] add no row.
        gain: Fraction in (0, 1] of the remaining gap a step may close.
        distances_m: Each pair's distance [m] at the last call (``detection_distance_m`` for
            pairs beyond it or skipped by the broad phase).
    """

    def __init__(self, robot: Robot, pairs: GeomPairs | Sequence[CollisionPair],
                 min_distance_m: float = 0.005, detection_distance_m: float = 0.1, gain: float = 0.85):
        """Resolve the pairs and precompute each body's dofs.

        Args:
            robot: The model pair.
            pairs: Resolved geom pairs, or named pairs to resolve.
            min_distance_m: Minimum distance [m].
            detection_distance_m: Detection distance [m] (> ``min_distance_m``). A step may move a
                pair by several centimetres, so keep it above the largest approach per step:
                a pair first seen inside its minimum distance can only be held there.
            gain: Fraction in (0, 1] of the gap a step may close.

        Raises:
            IKSetupError: Bad distances or gain, or an empty pair set.
        """
        if not 0.0 < gain <= 1.0:
            raise IKSetupError(f"collision avoidance gain must be in (0, 1]; got {gain!r}")
        if not (np.isfinite(min_distance_m) and np.isfinite(detection_distance_m)
                and detection_distance_m > min_distance_m):
            raise IKSetupError(f"collision detection distance ({detection_distance_m!r} m) must exceed the "
                               f"minimum distance ({min_distance_m!r} m), both finite")
        self.robot = robot
        self.pairs = pairs if isinstance(pairs, GeomPairs) else resolve_pairs(robot, pairs)
        if not len(self.pairs):
            raise IKSetupError("collision avoidance needs at least one geom pair")
        self.min_distance_m = float(min_distance_m)
        self.detection_distance_m = float(detection_distance_m)
        self.gain = float(gain)
        m = robot.mj_model
        self._data = mujoco.MjData(m)
        ids = self.pairs.ids
        self._g1, self._g2 = ids[:, 0].copy(), ids[:, 1].copy()
        self._geoms = np.unique(ids)
        self._incidence: np.ndarray | None = None  # (P, distinct geoms): +1 at geom 1, -1 at geom 2
        if len(ids) * len(self._geoms) <= INCIDENCE_MAX:
            rows = np.arange(len(ids))
            self._incidence = np.zeros((len(ids), len(self._geoms)))
            self._incidence[rows, np.searchsorted(self._geoms, self._g1)] = 1.0
            self._incidence[rows, np.searchsorted(self._geoms, self._g2)] = -1.0
        rbound = np.asarray(m.geom_rbound)
        self._rsum = rbound[self._g1] + rbound[self._g2]
        self._unbounded = (rbound[self._g1] <= 0.0) | (rbound[self._g2] <= 0.0)  # planes: always kept
        self._pair_list = [(int(a), int(b)) for a, b in ids]
        self._seg = np.zeros((len(ids), 6))  # witness points of each pair's last measurement
        self._seg_rows = list(self._seg)  # a view per pair, made once (MuJoCo writes into it)
        self._distance_terms: tuple[float, np.ndarray, list[tuple]] | None = None  # see _per_distance
        masks = body_dof_masks(robot)
        # the dofs moving geom 1 but not geom 2 (+1), geom 2 but not 1 (-1); shared dofs move both
        # witness points rigidly, which leaves their distance unchanged
        self._dmask = masks[m.geom_bodyid[self._g1]] - masks[m.geom_bodyid[self._g2]]
        self.distances_m = np.full(len(self.pairs), self.detection_distance_m)
        self._fromto = np.empty(6)
        self._cache: tuple[bytes, float, tuple[np.ndarray, np.ndarray, np.ndarray]] | None = None
        self._synced: bytes | None = None  # the q (bytes) the scratch data holds, when _measure set it

    def _per_distance(self) -> tuple[np.ndarray, list[tuple]]:
        """Each pair's squared broad-phase reach and ``mj_geomDistance`` arguments.

        Made once per detection distance; planes get an infinite reach (always kept).
        """
        dmax = self.detection_distance_m
        if self._distance_terms is None or self._distance_terms[0] != dmax:
            reach2 = (self._rsum + dmax) ** 2
            reach2[self._unbounded] = np.inf
            m, d = self.robot.mj_model, self._data
            args = [(m, d, a, b, dmax, row)
                    for (a, b), row in zip(self._pair_list, self._seg_rows, strict=True)]
            self._distance_terms = (dmax, reach2, args)
        return self._distance_terms[1], self._distance_terms[2]

    def candidates(self) -> np.ndarray:
        """Indices of the pairs the broad phase keeps at the last synced kinematics."""
        xpos = self._data.geom_xpos
        if self._incidence is not None:  # x_1 - x_2 of every pair by one product (exact: 0, +-1)
            diff = self._incidence @ xpos[self._geoms]
        else:
            diff = xpos[self._g1]
            diff -= xpos[self._g2]
        diff *= diff
        # .nonzero()[0]: flatnonzero's own work without its Python wrapper (~0.6 us)
        return (diff @ _ONES3 <= self._per_distance()[0]).nonzero()[0]

    def sync(self, q: np.ndarray) -> None:
        """Put MuJoCo's scratch data at ``q`` (nq,), Pinocchio convention (geom poses only)."""
        self.robot.plant_qpos(q, self._data.qpos)
        mujoco.mj_kinematics(self.robot.mj_model, self._data)
        self._synced = None

    def _measure(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pairs within the detection distance at ``q``: (indices (k,), distances (k,), fromto (k, 6)).

        Also fills ``distances_m``. The last measurement is kept and reused for the same ``q`` and
        detection distance.
        """
        key = q.tobytes()
        cache = self._cache
        if cache is not None and cache[0] == key and cache[1] == self.detection_distance_m:
            return cache[2]
        self.sync(q)
        self._synced = key
        dmax = self.detection_distance_m
        dist = self.distances_m
        dist.fill(dmax)
        candidates = self.candidates()
        distance, args = mujoco.mj_geomDistance, self._per_distance()[1]
        dist[candidates] = [distance(*args[k]) for k in candidates.tolist()]
        idx = (dist < dmax).nonzero()[0]  # (the others hold dmax)
        out = (idx, dist[idx], self._seg[idx])
        self._cache = (key, dmax, out)
        return out

    def compute_qp_inequalities(self, state: TaskState, dt: float) -> Constraint:
        """One row per pair within the detection distance (possibly none) at ``state``."""
        idx, dists, seg = self._measure(state.q)
        nv, k = state.nv, len(idx)
        if not k:
            return Constraint(np.zeros((0, nv)), np.zeros(0))
        # the pairs along columns, coordinates along rows: (3, k) blocks, so that numpy runs a few
        # inner loops of k (a (k, 3) array's columns are strided: k loops of 3, ~4x slower)
        nT_pT = np.dot(_SPLIT, seg.T)  # [p2 - p1; p1] (6, k), C-contiguous
        n, p = nT_pT[:3], nT_pT[3:]
        nn = _ONES3 @ (n * n)
        if min(nn.tolist()) < 1e-24:  # witness points coincide: use the line between the geoms' centres
            touching = nn < 1e-24
            if self._synced != state.q.tobytes():  # the scratch data moved on since: back to q
                self.sync(state.q)
            xpos = self._data.geom_xpos
            n[:, touching] = (xpos[self._g2[idx[touching]]] - xpos[self._g1[idx[touching]]]).T
            nn = _ONES3 @ (n * n)
        np.maximum(nn, 1e-300, out=nn)
        np.sqrt(nn, out=nn)
        n /= np.copysign(nn, dists, out=nn)  # the separating direction (unit, signed as d)
        # n^T J_p = [n; p x n]^T J_B, and p2 x n = p1 x n (p2 - p1 is along n): both witness points
        # share one row w, so -d'(dq) = w^T J (mask_1 - mask_2) dq, one (k, 6) @ (6, nv) product;
        # p x n from the outer products p n^T (each entry p_a n_b - p_b n_a, as a cross product),
        # written over p: the rows become w^T = [n; p x n]
        outer = p[:, None, :] * n[None, :, :]
        np.dot(_LEVI_CIVITA, outer.reshape(9, k), out=p)
        G = np.dot(nT_pT.T, state.data.J)
        G *= self._dmask[idx]
        h = dists - self.min_distance_m
        np.maximum(h, 0.0, out=h)
        h *= self.gain
        return Constraint(G, h)

    def guard_step(self, model: pin.Model, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """``dq`` halved until no pair ends below the minimum distance closer than it started.

        A pair already below the minimum at ``q`` may stay there but not close further. After
        ``MAX_HALVINGS`` halvings the step is zero.
        """
        self._measure(q)
        before = self.distances_m.copy()
        for _ in range(MAX_HALVINGS + 1):
            self._measure(pin.integrate(model, q, dq))
            after = self.distances_m
            if np.minimum.reduce(after) >= self.min_distance_m or not np.any(
                    (after < self.min_distance_m) & (after < before - 1e-12)):
                return dq
            dq = 0.5 * dq
        self._measure(q)  # no step: keep the rows of where we stay
        return np.zeros_like(dq)
