"""Differential-IK limits: inequalities ``G dq <= h`` on the step ``dq`` (nv,) in the tangent space.

All three limits here are boxes on ``dq`` in Pinocchio's convention, so ``BoxLimit`` also offers
them as bounds ``lower <= dq <= upper`` (the solver intersects the boxes and hands them to the
QP backend as ``lb``/``ub``). Index sets and constant bounds are computed once, at construction.

* ``JointPositionLimit``: ``gain (q_min - q) <= dq <= gain (q_max - q)`` on 1-dof joints with
  finite limits (revolute, prismatic; unbounded and multi-dof joints are skipped).
* ``JointVelocityLimit``: ``|dq_i| <= v_max,i dt``.
* ``FloatingBaseVelocityLimit``: ``|v_B| <= v_max dt``, ``|w_B| <= w_max dt`` per axis, in the
  base frame (Pinocchio's free-flyer velocity is already local, so this is a box too; mink's
  ``FreeJointVelocityLimit`` bounds the same quantities after rotating MuJoCo's world-frame
  linear velocity).
"""

from __future__ import annotations

import abc
from collections.abc import Mapping
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from mbctl.control.exceptions import IKSetupError
from mbctl.control.tasks.state import TaskState
from mbctl.robots.exceptions import UnknownNameError
from mbctl.robots.indexing import as_slice


class Constraint(NamedTuple):
    """Inequality ``G dq <= h``.

    Attributes:
        G: Constraint matrix (m, nv).
        h: Right-hand side (m,).
    """

    G: np.ndarray
    h: np.ndarray


class Limit(abc.ABC):
    """An inequality on the IK step ``dq``."""

    @abc.abstractmethod
    def compute_qp_inequalities(self, state: TaskState, dt: float) -> Constraint:
        """``(G, h)`` with ``G dq <= h`` at ``state`` for a step of duration ``dt`` [s]."""

    def guard_step(self, model: pin.Model, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """The step to take from ``q`` (nq,) instead of ``dq`` (nv,), checked beyond the linearisation.

        The QP keeps the linearised limit; a limit on a curved quantity (collision distances)
        may shorten the step here so that the limit holds at ``q (+) dq`` itself. Default: ``dq``.
        """
        return dq


class BoxLimit(Limit):
    """A limit of the form ``lower <= dq <= upper`` on some tangent indices.

    Attributes:
        state_dependent: False when the box depends only on ``dt`` (the solver then caches it).
    """

    state_dependent: bool = True

    @abc.abstractmethod
    def intersect_bounds(
        self, state: TaskState, dt: float, lower: np.ndarray, upper: np.ndarray
    ) -> None:
        """Tighten ``lower``/``upper`` (nv,) in place with this limit's box."""

    def compute_qp_inequalities(self, state: TaskState, dt: float) -> Constraint:
        """The box as ``[I; -I] dq <= [upper; -lower]`` on its finite entries."""
        nv = state.nv
        lower = np.full(nv, -np.inf)
        upper = np.full(nv, np.inf)
        self.intersect_bounds(state, dt, lower, upper)
        eye = np.eye(nv)
        up = np.isfinite(upper)
        lo = np.isfinite(lower)
        return Constraint(np.vstack([eye[up], -eye[lo]]), np.concatenate([upper[up], -lower[lo]]))


def _one_dof_joints(model: pin.Model) -> list[int]:
    return [j for j in range(1, model.njoints) if model.joints[j].nq == 1 and model.joints[j].nv == 1]


class JointPositionLimit(BoxLimit):
    """Keep 1-dof joints within their position limits: ``gain (q_min - q) <= dq <= gain (q_max - q)``.

    Attributes:
        idx_q: Configuration indices of the limited joints.
        idx_v: Tangent indices of the same joints.
        q_min: Lower limits [rad or m] (read-only).
        q_max: Upper limits [rad or m] (read-only).
        gain: Fraction in (0, 1] of the remaining range allowed per step.
    """

    def __init__(self, model: pin.Model, gain: float = 0.95, margin: float = 0.0):
        """Collect limited joints from ``model.lowerPositionLimit``/``upperPositionLimit``.

        Args:
            model: Pinocchio model.
            gain: Fraction in (0, 1] of the distance to a limit allowed per step.
            margin: Shrinks every range on both sides [rad or m].

        Raises:
            IKSetupError: ``gain`` outside (0, 1], or a range that the margin makes empty.
        """
        if not 0.0 < gain <= 1.0:
            raise IKSetupError(f"JointPositionLimit gain must be in (0, 1]; got {gain!r}")
        iq, iv, names = [], [], []
        for j in _one_dof_joints(model):
            q0 = model.joints[j].idx_q
            if np.isfinite(model.lowerPositionLimit[q0]) and np.isfinite(model.upperPositionLimit[q0]):
                iq.append(q0)
                iv.append(model.joints[j].idx_v)
                names.append(model.names[j])
        self.idx_q = np.array(iq, dtype=int)
        self.idx_v = np.array(iv, dtype=int)
        self.q_min = np.asarray(model.lowerPositionLimit)[self.idx_q] + margin
        self.q_max = np.asarray(model.upperPositionLimit)[self.idx_q] - margin
        bad = np.flatnonzero(self.q_min > self.q_max)
        if bad.size:
            raise IKSetupError(
                f"margin {margin!r} leaves an empty range for joints "
                f"{[names[i] for i in bad[:5]]}; use a smaller margin."
            )
        for arr in (self.idx_q, self.idx_v, self.q_min, self.q_max):
            arr.setflags(write=False)
        self._sq = as_slice(self.idx_q)
        self._sv = as_slice(self.idx_v)
        self.gain = float(gain)
        self.joint_names = tuple(names)
        # scratch and gain-scaled limits for the hot path (intersect_bounds runs every step)
        # (gain q_min; gain q_max) as one (2, n) array: both bounds by one subtraction
        self._gq_bounds = self.gain * np.stack([self.q_min, self.q_max])
        self._gq, self._lo_hi = np.empty(len(iq)), np.empty((2, len(iq)))
        self._lo, self._hi = self._lo_hi  # views of its rows

    def intersect_bounds(
        self, state: TaskState, dt: float, lower: np.ndarray, upper: np.ndarray
    ) -> None:
        """Tighten with ``gain (q_min - q)`` and ``gain (q_max - q)`` on the limited dofs."""
        gq = self._gq
        np.multiply(state.q[self._sq], self.gain, out=gq)
        np.subtract(self._gq_bounds, gq, out=self._lo_hi)
        lo, hi = self._lo, self._hi
        iv = self._sv
        if isinstance(iv, slice):  # contiguous dofs: tighten the views in place
            low, up = lower[iv], upper[iv]
            np.maximum(low, lo, out=low)
            np.minimum(up, hi, out=up)
        else:
            lower[iv] = np.maximum(lower[iv], lo)
            upper[iv] = np.minimum(upper[iv], hi)

    def margins(self, q: npt.ArrayLike) -> dict[str, tuple[float, float]]:
        """Distance to the lower and upper limit of each limited joint [rad or m], by name."""
        qa = np.asarray(q, dtype=float)[self.idx_q]
        return {
            n: (float(a), float(b))
            for n, a, b in zip(self.joint_names, qa - self.q_min, self.q_max - qa, strict=True)
        }


class _VelocityBox(BoxLimit):
    """``-v_max dt <= dq <= v_max dt`` on fixed tangent indices (depends on ``dt`` only).

    Attributes:
        idx_v: Tangent indices of the limited dofs (read-only).
        max_velocity: Speed bounds of those dofs [rad/s or m/s] (read-only).
    """

    state_dependent = False

    def _set_bounds(self, idx_v: npt.ArrayLike, max_velocity: npt.ArrayLike) -> None:
        self.idx_v = np.array(idx_v, dtype=int)
        self.max_velocity = np.array(max_velocity, dtype=float)
        self.idx_v.setflags(write=False)
        self.max_velocity.setflags(write=False)

    def intersect_bounds(
        self, state: TaskState, dt: float, lower: np.ndarray, upper: np.ndarray
    ) -> None:
        """Tighten with ``-v_max dt <= dq <= v_max dt``."""
        iv = self.idx_v
        step = self.max_velocity * dt
        lower[iv] = np.maximum(lower[iv], -step)
        upper[iv] = np.minimum(upper[iv], step)


class JointVelocityLimit(_VelocityBox):
    """``|dq_i| <= v_max,i dt`` on named 1-dof joints.

    Attributes:
        idx_v: Tangent indices of the limited joints.
        max_velocity: Limits [rad/s or m/s] (read-only).
    """

    def __init__(self, model: pin.Model, velocities: Mapping[str, float] | None = None):
        """Build the limit.

        Args:
            model: Pinocchio model.
            velocities: Maximum speed by joint name [rad/s or m/s]; None takes every 1-dof
                joint with a finite ``model.velocityLimit``.

        Raises:
            UnknownNameError: A joint name not in the model.
            IKSetupError: A multi-dof joint or a non-positive speed.
        """
        if velocities is None:
            velocities = {
                model.names[j]: float(model.velocityLimit[model.joints[j].idx_v])
                for j in _one_dof_joints(model)
                if np.isfinite(model.velocityLimit[model.joints[j].idx_v])
            }
        iv, vmax = [], []
        names = list(model.names)
        for name, speed in velocities.items():
            if name not in names:
                raise UnknownNameError("joint", name, names[1:])
            j = names.index(name)
            if model.joints[j].nv != 1:
                raise IKSetupError(
                    f"JointVelocityLimit takes 1-dof joints; {name!r} has nv={model.joints[j].nv} "
                    "(use FloatingBaseVelocityLimit for the free flyer)."
                )
            if not (np.isfinite(speed) and speed > 0.0):
                raise IKSetupError(f"max velocity of {name!r} must be > 0 [rad/s]; got {speed!r}")
            iv.append(model.joints[j].idx_v)
            vmax.append(float(speed))
        self._set_bounds(iv, vmax)


class FloatingBaseVelocityLimit(_VelocityBox):
    """Per-axis bounds on the free-flyer twist in the base frame: ``|v_B| <= v dt``, ``|w_B| <= w dt``.

    Attributes:
        idx_v: The six tangent indices of the free flyer.
        max_velocity: (6,) bounds, linear [m/s] then angular [rad/s] (read-only).
    """

    def __init__(
        self,
        model: pin.Model,
        linear: npt.ArrayLike = 1.0,
        angular: npt.ArrayLike = 2.0,
    ):
        """Build the limit.

        Args:
            model: Pinocchio model with a free-flyer joint.
            linear: Max base linear speed per axis [m/s], scalar or (3,), base frame.
            angular: Max base angular speed per axis [rad/s], scalar or (3,), base frame.

        Raises:
            IKSetupError: No free flyer, or non-positive bounds.
        """
        free = [j for j in range(1, model.njoints) if model.joints[j].shortname() == "JointModelFreeFlyer"]
        if not free:
            raise IKSetupError(
                "FloatingBaseVelocityLimit needs a free-flyer joint; the model's joints are "
                f"{[model.joints[j].shortname() for j in range(1, model.njoints)]}."
            )
        vmax = np.concatenate(
            [np.broadcast_to(np.asarray(linear, float), 3), np.broadcast_to(np.asarray(angular, float), 3)]
        )
        if not (np.all(np.isfinite(vmax)) and np.all(vmax > 0.0)):
            raise IKSetupError(f"floating-base velocity bounds must be > 0; got {vmax.tolist()}")
        start = model.joints[free[0]].idx_v
        self._set_bounds(np.arange(start, start + 6), vmax)
