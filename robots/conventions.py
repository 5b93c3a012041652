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

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from mbctl.robots.exceptions import StateError
from mbctl.robots.fastmath import (
    SMALL_VECTOR_MAX,
    WXYZ_FROM_XYZW,
    XYZW_FROM_WXYZ,
    all_finite,
    cross3,
    quat_xyzw_rotate,
    quat_xyzw_rotate_inverse,
    quat_xyzw_to_matrix,
)


def quat_wxyz_to_xyzw(quat_wxyz: npt.ArrayLike) -> np.ndarray:
    """Reorder quaternions (..., 4) from (w, x, y, z) to (x, y, z, w) (a new array)."""
    q = np.asarray(quat_wxyz, dtype=float)
    return q[..., list(XYZW_FROM_WXYZ)]


def quat_xyzw_to_wxyz(quat_xyzw: npt.ArrayLike) -> np.ndarray:
    """Reorder quaternions (..., 4) from (x, y, z, w) to (w, x, y, z) (a new array)."""
    q = np.asarray(quat_xyzw, dtype=float)
    return q[..., list(WXYZ_FROM_XYZW)]


def quat_xyzw_yaw(quat_xyzw: npt.ArrayLike) -> float | np.ndarray:
    """Yaw [rad] (Z-Y-X, as ``pin.rpy.matrixToRpy``) of unit quaternions (4,) or (k, 4) (x, y, z, w).

    One quaternion gives a float (plain floats: cheap in a loop's cycle), k give an array (k,).
    """
    q = np.asarray(quat_xyzw, dtype=float)
    if q.ndim == 1:
        x, y, z, w = q.tolist()
        return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    x, y, z, w = q.T
    return np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def rotation_from_quat_xyzw(quat_xyzw: npt.ArrayLike) -> np.ndarray:
    """Rotation matrix ``R`` (3, 3) of a non-zero quaternion (x, y, z, w), normalized first.

    Raises:
        StateError: A zero quaternion.
    """
    return quat_xyzw_to_matrix(np.asarray(quat_xyzw, dtype=float).tolist())


@dataclass(frozen=True)
class JointLayout:
    """Where one joint's coordinates sit in the robot's q and v, and in the plant's qpos and qvel.

    The robot's q and v (both conventions) hold the robot's joints only, in MuJoCo's joint
    order; the plant's qpos and qvel may hold scene coordinates too (a free box), so a joint's
    plant address can differ from its robot index.

    Attributes:
        name: Joint name.
        kind: "free", "ball", "hinge" or "slide".
        idx_q: First index in q.
        idx_v: First index in v.
        nq: Number of configuration coordinates.
        nv: Number of velocity coordinates.
        qposadr: First index in the plant's ``qpos`` (default: ``idx_q``).
        dofadr: First index in the plant's ``qvel`` (default: ``idx_v``).
    """

    name: str
    kind: str
    idx_q: int
    idx_v: int
    nq: int
    nv: int
    qposadr: int = -1
    dofadr: int = -1

    def __post_init__(self) -> None:
        if self.qposadr < 0:
            object.__setattr__(self, "qposadr", self.idx_q)
        if self.dofadr < 0:
            object.__setattr__(self, "dofadr", self.idx_v)

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
                perm_pin_from_mj[quat_at : quat_at + 4] = quat_at + np.array(XYZW_FROM_WXYZ)
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
        return [quat_xyzw_to_matrix(q_pin[iq + 3 : iq + 7].tolist()) for iq, _ in self._free]

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
        velocity with scalar arithmetic (``fastmath.quat_xyzw_rotate_inverse``; building and
        applying a 3x3 numpy rotation costs ~8x more at this size).

        Args:
            q_mj: MuJoCo qpos (nq,) (free-joint quaternion (w, x, y, z), any non-zero norm).
            v_mj: MuJoCo qvel (nv,) (free-joint linear velocity ``v_WB_W`` [m/s] in W).

        Returns:
            Pinocchio ``q`` (nq,) and ``v`` (nv,) (free-joint linear velocity ``v_WB_B`` in B).

        Raises:
            StateError: A zero free-joint quaternion.
        """
        q = q_mj[self._perm_pin_from_mj] if self.has_quaternions else q_mj.copy()
        v = v_mj.copy()
        for iq, iv in self._free:
            v[iv : iv + 3] = quat_xyzw_rotate_inverse(q[iq + 3 : iq + 7].tolist(), v[iv : iv + 3].tolist())
        return q, v

    # ------------------------------------------------------------------ batches (cross-check)
    def qs_pin_to_mj(self, q_pin: np.ndarray) -> np.ndarray:
        """Pinocchio configurations (n, nq) -> MuJoCo qpos (n, nq), a new array."""
        return np.asarray(q_pin, dtype=float)[:, self._perm_mj_from_pin]

    @property
    def free_v(self) -> list[int]:
        """Index in v of each free joint's linear velocity (where ``T`` is not the identity)."""
        return [iv for _, iv in self._free]

    def velocity_maps(self, q_pin: np.ndarray) -> VelocityMaps:
        """``T(q)`` of each configuration of a batch (n, nq), applied without (nv, nv) matrices."""
        q = np.asarray(q_pin, dtype=float)
        R = np.zeros((len(q), len(self._free), 3, 3))
        for k, (iq, _) in enumerate(self._free):
            R[:, k] = quats_xyzw_to_matrices(q[:, iq + 3 : iq + 7])
        return VelocityMaps([iv for _, iv in self._free], R)

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
        q = np.asarray(q_pin, dtype=float)
        v = np.asarray(v_pin, dtype=float)
        for iq, iv in self._free:
            w_x_v = cross3(v[iv + 3 : iv + 6].tolist(), v[iv : iv + 3].tolist())
            out[iv : iv + 3] = quat_xyzw_rotate(q[iq + 3 : iq + 7].tolist(), w_x_v)
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


def quats_xyzw_to_matrices(quat_xyzw: np.ndarray) -> np.ndarray:
    """Rotation matrices (n, 3, 3) of quaternions (n, 4) (x, y, z, w), each normalized first."""
    x, y, z, w = np.asarray(quat_xyzw, dtype=float).T
    s = 2.0 / (x * x + y * y + z * z + w * w)
    return np.stack([
        1.0 - s * (y * y + z * z), s * (x * y - z * w), s * (x * z + y * w),
        s * (x * y + z * w), 1.0 - s * (x * x + z * z), s * (y * z - x * w),
        s * (x * z - y * w), s * (y * z + x * w), 1.0 - s * (x * x + y * y),
    ], axis=-1).reshape(-1, 3, 3)


class VelocityMaps:
    """``T(q)`` for a batch of n configurations, applied block by block.

    ``T`` is the identity except ``R_WB`` on each free joint's linear-velocity block, so every
    product touches only those three rows or columns (a (nv, nv) product per state would cost
    ~100x more on the G1). Arrays carry the batch on their first axis.

    Attributes:
        free_v: Index in v of each free joint's linear velocity.
        R: ``R_WB`` of each free joint (n, k, 3, 3).
    """

    def __init__(self, free_v: Sequence[int], R: np.ndarray):
        self.free_v = list(free_v)
        self.R = R

    def to_mj(self, x: np.ndarray) -> np.ndarray:
        """``T x``: velocities or generalized forces (n, ..., nv) from Pinocchio to MuJoCo (new array)."""
        out = np.array(x, dtype=float)
        for k, iv in enumerate(self.free_v):
            out[..., iv : iv + 3] = np.einsum("nij,n...j->n...i", self.R[:, k], x[..., iv : iv + 3])
        return out

    def to_pin(self, x: np.ndarray) -> np.ndarray:
        """``T^T x`` in place: x (n, ..., nv) from MuJoCo to Pinocchio; returns ``x``."""
        for k, iv in enumerate(self.free_v):
            x[..., iv : iv + 3] = np.einsum("nji,n...j->n...i", self.R[:, k], x[..., iv : iv + 3])
        return x

    def dot_v(self, v_pin: np.ndarray) -> np.ndarray:
        """``Tdot v`` (n, nv): ``R_WB (w_B x v_B)`` on each free joint's linear part."""
        out = np.zeros(np.shape(v_pin))
        for k, iv in enumerate(self.free_v):
            (vx, vy, vz), (wx, wy, wz) = v_pin[:, iv : iv + 3].T, v_pin[:, iv + 3 : iv + 6].T
            # w x v without np.cross (5x slower at this size)
            w_x_v = np.stack([wy * vz - wz * vy, wz * vx - wx * vz, wx * vy - wy * vx], axis=1)
            out[:, iv : iv + 3] = np.einsum("nij,nj->ni", self.R[:, k], w_x_v)
        return out

    def right(self, J: np.ndarray) -> np.ndarray:
        """``J T`` in place: J (n, ..., m, nv), e.g. MuJoCo Jacobians into Pinocchio's columns."""
        for k, iv in enumerate(self.free_v):
            block = J[..., iv : iv + 3]
            rows = block.reshape(len(J), -1, 3)  # a copy when J is not contiguous: written back below
            block[...] = np.matmul(rows, self.R[:, k]).reshape(block.shape)
        return J

    def right_packed(self, J: np.ndarray, blocks: Sequence[tuple[int, int]]) -> np.ndarray:
        """``J T`` in place for Jacobian entries packed along the last axis: J (n, r, L).

        ``blocks[k] = (start, F)``: free joint k's linear columns x, y, z of F row blocks (frames)
        sit at ``start``, ``start + F`` and ``start + 2 F``; no other entry changes.
        """
        for (start, F), R in zip(blocks, self.R.swapaxes(0, 1), strict=True):
            X, Y, Z = (J[..., start + i * F : start + (i + 1) * F].copy() for i in range(3))
            R = R[:, None, None]  # (n, 1, 1, 3, 3): one rotation per state
            for i in range(3):
                J[..., start + i * F : start + (i + 1) * F] = (
                    X * R[..., 0, i] + Y * R[..., 1, i] + Z * R[..., 2, i]
                )
        return J

    def congruence(self, M: np.ndarray) -> np.ndarray:
        """``T^T M T`` in place: M (n, nv, nv), MuJoCo's mass matrix into Pinocchio's."""
        self.right(M)
        for k, iv in enumerate(self.free_v):
            M[:, iv : iv + 3, :] = self.R[:, k].swapaxes(1, 2) @ M[:, iv : iv + 3, :]
        return M


def _check_vector(x: npt.ArrayLike, n: int, what: str) -> np.ndarray:
    try:
        arr = np.asarray(x, dtype=float)
    except (TypeError, ValueError) as exc:
        raise StateError(f"{what} must be a numeric vector of shape ({n},); got {x!r}") from exc
    if arr.shape != (n,):
        raise StateError(f"{what} must have shape ({n},); got shape {arr.shape}")
    if n <= SMALL_VECTOR_MAX and all_finite(arr.tolist()):
        return arr  # the common case, without numpy's per-call cost
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        raise StateError(
            f"{what} must be finite; entries {bad.tolist()} are {arr[bad].tolist()}"
        )
    return arr
