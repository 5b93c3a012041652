"""Tasks whose Jacobian is a constant 0/1 diagonal: the QPs add them to H's diagonal directly.

``W_t = diag(cost mask)`` contributes ``cost^2 mask`` to the diagonal of ``H = W^T W`` and
``-cost mask r_t`` to c, so the stack (:mod:`mbctl.control.tasks.stack`) adds those instead of
stacking nv more rows into the least-squares matrix.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from mbctl.control.tasks.base import AccelerationGains, Task, floating_dofs
from mbctl.control.tasks.frame import pin_model
from mbctl.control.tasks.state import DynamicsState, TaskState


class DiagonalTask(Task):
    """A task whose Jacobian is ``diag(mask)`` (nv, nv): identity on every dof but the free flyer's.

    Attributes:
        model: The Pinocchio model.
        mask: (nv,) 1.0 where the task acts, 0.0 on the free flyer's dofs (read-only).
        is_diagonal: Whether the Jacobian really is ``diag(mask)`` for this model (the stack takes
            the diagonal shortcut only then).
    """

    is_diagonal: bool = True

    def __init__(self, name: str, model: TaskState | pin.Model, cost: npt.ArrayLike, gain: float,
                 lm_damping: float, servo: AccelerationGains | None = None):
        self.model = pin_model(model)
        super().__init__(name, self.model.nv, cost, gain, lm_damping, servo)
        self._free_idx = floating_dofs(self.model)
        self._jacobian = np.eye(self.model.nv)
        self._jacobian[self._free_idx, self._free_idx] = 0.0
        self._jacobian.setflags(write=False)
        self.mask = np.diag(self._jacobian).copy()
        self.mask.setflags(write=False)
        self._cost2_mask: tuple[np.ndarray, np.ndarray] | None = None

    def masked_error(self, state: TaskState) -> np.ndarray:
        """The error (nv,) where ``mask`` is 1 (entries where it is 0 may hold anything)."""
        return self.compute_error(state)

    def masked_desired_acceleration(self, state: DynamicsState) -> np.ndarray:
        """``a_des`` (nv,) where ``mask`` is 1 (entries where it is 0 may hold anything)."""
        return self.desired_acceleration(state, self._jacobian)

    def add_acceleration_term(self, state: DynamicsState, c: np.ndarray, tmp: np.ndarray) -> None:
        """``c -= cost^2 mask a_des``: this task's part of the objective's linear term (tmp: (nv,) scratch).

        Its rows ``W_t = diag(cost mask)``, ``r_t = cost mask a_des`` give ``c_t = -W_t^T r_t``.
        """
        np.multiply(self.cost2_mask(), self.masked_desired_acceleration(state), out=tmp)
        c -= tmp

    def cost2_mask(self) -> np.ndarray:
        """``cost^2 mask`` (nv,): this task's contribution to H's diagonal (cached per cost)."""
        cached = self._cost2_mask
        if cached is None or cached[0] is not self._cost:
            cached = (self._cost, self._cost * self._cost * self.mask)
            self._cost2_mask = cached
        return cached[1]
