"""Joint posture: ``e = q ⊖ q_target`` (nv,) (``pin.difference``), free-flyer entries zero.

Velocity level: ``J_e = de/dq`` (nv, nv): the identity for 1-dof joints and the exact
``pin.dDifference`` block for ball joints (mink uses the identity there, a first-order
approximation), free-flyer rows zero (the base is not pulled to a posture), as in mink.
Acceleration level: ``J = diag(mask)`` (the joint dofs), no drift, ``a_des = -kp e - kd v``
(the target at rest) on the joint dofs.
"""

from __future__ import annotations

from typing import cast

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from mbctl.control.exceptions import TaskSetupError
from mbctl.control.tasks.base import AccelerationGains
from mbctl.control.tasks.diagonal import DiagonalTask
from mbctl.control.tasks.residuals import TaskResidual
from mbctl.control.tasks.state import DynamicsState, TaskState
from mbctl.robots.indexing import as_slice


class PostureTask(DiagonalTask):
    """Joint posture regulariser: ``e = q ⊖ q_target`` (nv,), ``J = de/dq`` (nv, nv)."""

    regularizing = True

    def __init__(
        self,
        model: TaskState | pin.Model,
        cost: npt.ArrayLike = 1e-2,
        gain: float = 1.0,
        lm_damping: float = 0.0,
        name: str = "posture",
        servo: AccelerationGains | None = None,
    ):
        """Create the task (set a target before solving).

        Args:
            model: Pinocchio model or task state.
            cost: Weight(s) [cost]/[rad], scalar or (nv,).
            gain: Velocity level: fraction of the error corrected per step, in [0, 1].
            lm_damping: Velocity level: Levenberg-Marquardt scale [-].
            name: Report label.
            servo: Acceleration level: PD gains.

        Raises:
            TaskSetupError: Invalid cost, gain or damping.
        """
        super().__init__(name, model, cost, gain, lm_damping, servo)
        self._free = as_slice(self._free_idx)
        self.is_diagonal = all(joint.nv == 1 or joint.shortname() == "JointModelFreeFlyer"
                               for joint in list(self.model.joints)[1:])
        self._target: np.ndarray | None = None
        self._zero = np.zeros(self.model.nv)
        self._zero.setflags(write=False)
        # (v index, q index) of the joints whose configuration is their coordinate (nq = nv = 1, so
        # q ⊖ q_target = q - q_target there), when every joint but the free flyer's is one; else None
        moving = [j for j in list(self.model.joints)[1:]
                  if j.nv > 0 and j.shortname() != "JointModelFreeFlyer"]
        self._coordinates = None
        if all(j.nq == j.nv == 1 for j in moving):
            self._coordinates = (np.array([j.idx_v for j in moving], dtype=int),
                                 np.array([j.idx_q for j in moving], dtype=int))

    def set_target(self, target_q: npt.ArrayLike) -> None:
        """Set the target configuration (nq,), Pinocchio convention (at rest).

        Raises:
            TaskSetupError: Wrong shape or non-finite entries.
        """
        q = np.asarray(target_q, dtype=float).copy()
        if q.shape != (self.model.nq,) or not np.all(np.isfinite(q)):
            raise TaskSetupError(f"{self.name}: target must be a finite ({self.model.nq},) configuration; "
                                 f"got shape {q.shape}")
        self._target = q

    @property
    def target(self) -> np.ndarray:
        """The target configuration (nq,) (a copy).

        Raises:
            TaskSetupError: No target set yet.
        """
        if self._target is None:
            raise self._no_target()
        return self._target.copy()

    def set_target_from_state(self, state: TaskState) -> None:
        """Set the target to the current configuration."""
        self.set_target(state.q)

    def compute_error(self, state: TaskState) -> np.ndarray:
        """``q ⊖ q_target`` (nv,), free-flyer entries zeroed."""
        if self._target is None:
            raise self._no_target()
        e = pin.difference(self.model, self._target, state.q)
        e[self._free] = 0.0
        return e

    def masked_error(self, state: TaskState) -> np.ndarray:
        """``q ⊖ q_target`` (nv,) with the free-flyer entries left as they are (the mask drops them)."""
        if self._target is None:
            raise self._no_target()
        return pin.difference(self.model, self._target, state.q)

    def compute_jacobian(self, state: TaskState) -> np.ndarray:
        """``d(q ⊖ q_target)/dq`` (nv, nv), free-flyer rows zeroed.

        The identity (constant, read-only) unless the model has ball joints.
        """
        if self.is_diagonal:
            return self._jacobian
        if self._target is None:
            raise self._no_target()
        J = pin.dDifference(self.model, self._target, state.q, pin.ArgumentPosition.ARG1)
        J[self._free_idx, :] = 0.0
        return J

    def jacobian_and_drift(self, state: DynamicsState) -> tuple[np.ndarray, np.ndarray]:
        """``(diag(mask), 0)``: the joint dofs' accelerations."""
        return self._jacobian, self._zero

    def desired_acceleration(self, state: DynamicsState, J: np.ndarray) -> np.ndarray:
        """``-kp e - kd v`` (nv,) on the joint dofs, 0 on the free flyer's."""
        a = self.compute_error(state)  # free-flyer entries already zero
        a *= -self._kp
        a -= self._kd * state.v
        a *= self.mask
        return a

    def masked_desired_acceleration(self, state: DynamicsState) -> np.ndarray:
        """``-kp e - kd v`` (nv,), the free flyer's entries left as they are (the mask drops them)."""
        a = self.masked_error(state)
        a *= -self._kp
        tmp = self._acceleration_scratch()  # kd v, without a temporary
        np.multiply(state.v, self._kd, out=tmp)
        a -= tmp
        return a

    def add_acceleration_term(self, state: DynamicsState, c: np.ndarray, tmp: np.ndarray) -> None:
        """``c += kp cost^2 mask e + kd cost^2 mask v`` (``a_des = -kp e - kd v``; products cached).

        When every joint's configuration is its coordinate, ``e = q - q_target`` on the masked dofs
        and the term is one linear map of the state's ``[q; v]`` less a constant:
        ``K [q; v] - kp cost^2 mask q_target`` (three numpy calls instead of pin.difference and four).
        """
        if self._target is None:
            raise self._no_target()
        cached = self.__dict__.get("_acceleration_gains")
        if cached is None or cached[0] is not self._cost or cached[1:3] != (self._kp, self._kd):
            cached = self._acceleration_cache()
        K = cached[5]
        if K is None:
            e = self.masked_error(state)
            e *= cached[3]
            np.multiply(state.v, cached[4], out=tmp)
            e += tmp
            c += e
            return
        if cached[6] is not self._target:  # kp cost^2 mask q_target, once per target
            iv, iq = cast(tuple[np.ndarray, np.ndarray], self._coordinates)
            cached[7][iv] = cached[3][iv] * self._target[iq]
            self.__dict__["_acceleration_gains"] = cached = (*cached[:6], self._target, cached[7])
        np.dot(K, state.qv, out=tmp)
        tmp -= cached[7]
        c += tmp

    def _acceleration_cache(self) -> tuple:
        """Rebuild the cache of :meth:`add_acceleration_term` for the present cost and gains.

        Returns:
            (cost, kp, kd, kp cost^2 mask, kd cost^2 mask, K or None, the target its constant was made
            for (None: none yet), the constant ``kp cost^2 mask q_target``).
        """
        cost2_mask = self.cost2_mask()
        kp_c, kd_c = self._kp * cost2_mask, self._kd * cost2_mask
        K = None
        if self._coordinates is not None:
            nq, nv = self.model.nq, self.model.nv
            iv, iq = self._coordinates
            K = np.zeros((nv, nq + nv))
            K[iv, iq], K[iv, nq + iv] = kp_c[iv], kd_c[iv]
        cached = (self._cost, self._kp, self._kd, kp_c, kd_c, K, None, np.zeros(self.model.nv))
        self.__dict__["_acceleration_gains"] = cached
        return cached

    def residual(self, state: TaskState) -> TaskResidual:
        """Joint-space distance to the target [rad, or m for slide joints] (a regulariser's)."""
        return TaskResidual(deviation=float(np.linalg.norm(self.compute_error(state))))
