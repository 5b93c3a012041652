"""Conversions between Pinocchio's and MuJoCo's state conventions, in one place.

Notation (Drake monograms): W is the world frame, B a floating base body. ``R_WB`` rotates
base-frame vectors into the world frame.

=============  ===============================  ===============================
quantity       Pinocchio (the public convention) MuJoCo
=============  ===============================  ===============================
free-joint q   ``p_WB``, ``quat_xyzw``           ``p_WB``, ``quat_wxyz``
free-joint v   ``v_WB_B`` (local), ``w_WB_B``    ``v_WB_W`` (world), ``w_WB_B``
ball-joint q   ``quat_xyzw``                     ``quat_wxyz``
ball-joint v   ``w`` in the child frame          ``w`` in the child frame
=============  ===============================  ===============================

The velocity map is linear, ``v_mj = T(q) v_pin`` with ``T = blockdiag(R_WB, I)`` on each free
joint and identity elsewhere. Therefore:

* generalized forces: ``tau_pin = T^T tau_mj`` and ``tau_mj = T tau_pin`` (T is orthogonal);
* accelerations: ``a_mj = T a_pin + Tdot v_pin`` with ``Tdot v_pin = [R_WB (w x v_B); 0]``;
* mass matrix: ``M_pin = T^T M_mj T``;
* bias forces: ``b_pin = T^T (b_mj + M_mj Tdot v_pin)`` — the extra term the frame change adds.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from mbctl.robots.exceptions import StateError


def quat_wxyz_to_xyzw(quat_wxyz: npt.ArrayLike) -> np.ndarray:
    """Reorder a quaternion (w, x, y, z) -> (x, y, z, w)."""
    q = np.asarray(quat_wxyz, dtype=float)
    return q[..., [1, 2, 3, 0]]


def quat_xyzw_to_wxyz(quat_xyzw: npt.ArrayLike) -> np.ndarray:
    """Reorder a quaternion (x, y, z, w) -> (w, x, y, z)."""
    q = np.asarray(quat_xyzw, dtype=float)
    return q[..., [3, 0, 1, 2]]


def rotation_from_quat_xyzw(quat_xyzw: np.ndarray) -> np.ndarray:
    """Rotation matrix ``R`` (3, 3) of a quaternion (x, y, z, w); normalizes first."""
    x, y, z, w = quat_xyzw / np.linalg.norm(quat_xyzw)
    # Written out (not pin.Quaternion) because it runs on every state conversion of a
    # floating-base robot, where the Eigen round trip costs more than these 9 products.
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


@dataclass(frozen=True)
class JointLayout:
    """Where one joint's coordinates sit; identical in both engines (same order, same sizes).

    Attributes:
        name: Joint name.
        kind: "free", "ball", "hinge" or "slide".
        idx_q: First index in q.
        idx_v: First index in v.
        nq: Number of configuration coordinates.
        nv: Number of velocity coordinates.
    """

    name: str
    kind: str
    idx_q: int
    idx_v: int
    nq: int
    nv: int

    @property
    def q_slice(self) -> slice:
        """Slice of this joint in q (both conventions)."""
        return slice(self.idx_q, self.idx_q + self.nq)

    @property
    def v_slice(self) -> slice:
        """Slice of this joint in v (both conventions)."""
        return slice(self.idx_v, self.idx_v + self.nv)


class StateConverter:
    """Converts q, v, accelerations and generalized forces between Pinocchio and MuJoCo.

    Index arrays are derived once from the joint layout; a robot without free or ball joints
    takes a copy-only fast path.
    """

    def __init__(self, joints: Sequence[JointLayout], nq: int, nv: int):
        self.nq = nq
        self.nv = nv
        self._free = [(j.idx_q, j.idx_v) for j in joints if j.kind == "free"]
        perm_pin_from_mj = np.arange(nq)
        for j in joints:
            quat_at = j.idx_q + 3 if j.kind == "free" else j.idx_q if j.kind == "ball" else None
            if quat_at is not None:
                # pin (x, y, z, w) <- mj (w, x, y, z)
                perm_pin_from_mj[quat_at : quat_at + 4] = quat_at + np.array([1, 2, 3, 0])
        self._perm_pin_from_mj = perm_pin_from_mj
        self._perm_mj_from_pin = np.argsort(perm_pin_from_mj)
        self.has_quaternions = bool(np.any(perm_pin_from_mj != np.arange(nq)))

    # ------------------------------------------------------------------ validation
    def check_q(self, q: npt.ArrayLike, what: str = "q") -> np.ndarray:
        """``q`` as a float array of shape (nq,), or StateError naming the problem."""
        return _check_vector(q, self.nq, what)

    def check_v(self, v: npt.ArrayLike, what: str = "v") -> np.ndarray:
        """``v`` as a float array of shape (nv,), or StateError naming the problem."""
        return _check_vector(v, self.nv, what)

    # ------------------------------------------------------------------ configuration
    def q_mj_to_pin(self, q_mj: npt.ArrayLike) -> np.ndarray:
        """MuJoCo qpos (nq,) -> Pinocchio q (nq,) (quaternions become x, y, z, w)."""
        return np.asarray(q_mj, dtype=float)[self._perm_pin_from_mj]

    def q_pin_to_mj(self, q_pin: npt.ArrayLike) -> np.ndarray:
        """Pinocchio q (nq,) -> MuJoCo qpos (nq,) (quaternions become w, x, y, z)."""
        return np.asarray(q_pin, dtype=float)[self._perm_mj_from_pin]

    # ------------------------------------------------------------------ velocity map T(q)
    def _rotations(self, q_pin: np.ndarray) -> list[np.ndarray]:
        return [rotation_from_quat_xyzw(q_pin[iq + 3 : iq + 7]) for iq, _ in self._free]

    def v_pin_to_mj(self, q_pin: npt.ArrayLike, v_pin: npt.ArrayLike) -> np.ndarray:
        """``v_mj = T(q) v_pin``: free-joint linear velocity from base frame to world frame."""
        out = np.array(v_pin, dtype=float)
        for (_, iv), R_WB in zip(self._free, self._rotations(np.asarray(q_pin)), strict=True):
            out[iv : iv + 3] = R_WB @ out[iv : iv + 3]
        return out

    def v_mj_to_pin(self, q_pin: npt.ArrayLike, v_mj: npt.ArrayLike) -> np.ndarray:
        """``v_pin = T(q)^T v_mj``: free-joint linear velocity from world frame to base frame."""
        out = np.array(v_mj, dtype=float)
        for (_, iv), R_WB in zip(self._free, self._rotations(np.asarray(q_pin)), strict=True):
            out[iv : iv + 3] = R_WB.T @ out[iv : iv + 3]
        return out

    def state_mj_to_pin(self, q_mj: np.ndarray, v_mj: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """MuJoCo (qpos, qvel) -> Pinocchio (q, v), new arrays; the per-cycle state read.

        Equivalent to ``q_mj_to_pin`` then ``v_mj_to_pin`` but rotates each free joint's linear
        velocity with scalar arithmetic (a 3x3 numpy rotation costs ~10x more at this size).
        """
        q = q_mj[self._perm_pin_from_mj] if self.has_quaternions else q_mj.copy()
        v = v_mj.copy()
        for iq, iv in self._free:
            x, y, z, w = q[iq + 3 : iq + 7].tolist()
            vx, vy, vz = v[iv : iv + 3].tolist()
            s = 2.0 / (x * x + y * y + z * z + w * w)  # exact for non-unit quaternions too
            # v_B = R_WB^T v_W, with R_WB written out from the quaternion.
            v[iv] = (1 - s * (y * y + z * z)) * vx + s * (x * y + z * w) * vy + s * (x * z - y * w) * vz
            v[iv + 1] = s * (x * y - z * w) * vx + (1 - s * (x * x + z * z)) * vy + s * (y * z + x * w) * vz
            v[iv + 2] = s * (x * z + y * w) * vx + s * (y * z - x * w) * vy + (1 - s * (x * x + y * y)) * vz
        return q, v

    # generalized forces transform like velocities because T is orthogonal.
    force_pin_to_mj = v_pin_to_mj
    force_mj_to_pin = v_mj_to_pin

    def velocity_map(self, q_pin: npt.ArrayLike) -> np.ndarray:
        """``T(q)`` (nv, nv) with ``v_mj = T v_pin``."""
        T = np.eye(self.nv)
        for (_, iv), R_WB in zip(self._free, self._rotations(np.asarray(q_pin)), strict=True):
            T[iv : iv + 3, iv : iv + 3] = R_WB
        return T

    def velocity_map_dot_v(self, q_pin: npt.ArrayLike, v_pin: npt.ArrayLike) -> np.ndarray:
        """``Tdot(q, v) v`` (nv,): ``R_WB (w_B x v_B)`` on each free joint's linear part."""
        out = np.zeros(self.nv)
        v = np.asarray(v_pin, dtype=float)
        for (_, iv), R_WB in zip(self._free, self._rotations(np.asarray(q_pin)), strict=True):
            out[iv : iv + 3] = R_WB @ _cross3(v[iv + 3 : iv + 6], v[iv : iv + 3])
        return out

    # ------------------------------------------------------------------ accelerations
    def a_pin_to_mj(self, q_pin: npt.ArrayLike, v_pin: npt.ArrayLike, a_pin: npt.ArrayLike):
        """``a_mj = T a_pin + Tdot v_pin`` (nv,)."""
        return self.v_pin_to_mj(q_pin, a_pin) + self.velocity_map_dot_v(q_pin, v_pin)

    def a_mj_to_pin(self, q_pin: npt.ArrayLike, v_pin: npt.ArrayLike, a_mj: npt.ArrayLike):
        """``a_pin = T^T (a_mj - Tdot v_pin)`` (nv,)."""
        return self.v_mj_to_pin(q_pin, np.asarray(a_mj) - self.velocity_map_dot_v(q_pin, v_pin))

    def mass_matrix_mj_to_pin(self, q_pin: npt.ArrayLike, M_mj: np.ndarray) -> np.ndarray:
        """``M_pin = T^T M_mj T`` (nv, nv)."""
        T = self.velocity_map(q_pin)
        return T.T @ M_mj @ T

    def bias_mj_to_pin(
        self, q_pin: npt.ArrayLike, v_pin: npt.ArrayLike, M_mj: np.ndarray, b_mj: np.ndarray
    ) -> np.ndarray:
        """``b_pin = T^T (b_mj + M_mj Tdot v_pin)`` (nv,)."""
        extra = M_mj @ self.velocity_map_dot_v(q_pin, v_pin)
        return self.force_mj_to_pin(q_pin, np.asarray(b_mj) + extra)


def _cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a x b`` for two (3,) vectors; np.cross costs ~20 us per call, this ~1 us."""
    a0, a1, a2 = a.tolist()
    b0, b1, b2 = b.tolist()
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def _check_vector(x: npt.ArrayLike, n: int, what: str) -> np.ndarray:
    try:
        arr = np.asarray(x, dtype=float)
    except (TypeError, ValueError) as exc:
        raise StateError(f"{what} must be a numeric vector of shape ({n},); got {x!r}") from exc
    if arr.shape != (n,):
        raise StateError(f"{what} must have shape ({n},); got shape {arr.shape}")
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        raise StateError(
            f"{what} must be finite; entries {bad.tolist()} are {arr[bad].tolist()}"
        )
    return arr
