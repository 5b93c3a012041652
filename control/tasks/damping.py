"""Minimum motion: ``e = 0``, ``J = diag(mask)`` (free-flyer rows zero), gain 0 (mink's ``DampingTask``).

It adds ``sum_i cost_i^2 dq_i^2`` to the IK objective. It has no acceleration-level form (the
whole-body QP has its own acceleration regularisation).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from mbctl.control.tasks.diagonal import DiagonalTask
from mbctl.control.tasks.residuals import TaskResidual
from mbctl.control.tasks.state import TaskState


class DampingTask(DiagonalTask):
    """Minimum-motion regulariser: ``e = 0``, ``J = I`` (free-flyer rows zero), gain 0."""

    regularizing = True

    def __init__(self, model: TaskState | pin.Model, cost: npt.ArrayLike = 1e-3, name: str = "damping"):
        """Create the task.

        Args:
            model: Pinocchio model or task state.
            cost: Weight(s) [cost]/[rad], scalar or (nv,).
            name: Report label.

        Raises:
            TaskSetupError: Invalid cost.
        """
        super().__init__(name, model, cost, 0.0, 0.0)
        self._zero = np.zeros(self.model.nv)
        self._zero.setflags(write=False)

    def compute_error(self, state: TaskState) -> np.ndarray:
        """Zero (nv,)."""
        return self._zero

    def compute_jacobian(self, state: TaskState) -> np.ndarray:
        """Identity (nv, nv) with free-flyer rows zeroed."""
        return self._jacobian

    def residual(self, state: TaskState) -> TaskResidual:
        """Zero deviation (a regulariser has no target)."""
        return TaskResidual(deviation=0.0)
