"""Centroidal angular momentum to zero: an acceleration-level task (inverse dynamics only).

``h = A_g[3:] v`` [kg m^2/s] is the angular momentum about the CoM. Rows: ``J = A_g[3:]``, drift
``dA_g[3:] v``, ``a_des = -kd h`` (a damper; ``kp`` unused: there is no angular "position").
At the velocity level there is no configuration error, so it has no IK form.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from mbctl.control.exceptions import TaskSetupError
from mbctl.control.tasks.base import AccelerationGains, Task
from mbctl.control.tasks.residuals import TaskResidual
from mbctl.control.tasks.state import DynamicsState, TaskState


class AngularMomentumTask(Task):
    """Damp the centroidal angular momentum: ``J = A_g[3:]``, ``Jdot v = dA_g[3:] v``, ``a_des = -kd h``."""

    regularizing = True

    def __init__(self, cost: npt.ArrayLike = 1.0, name: str = "angular momentum",
                 servo: AccelerationGains | None = None):
        """Create the task.

        Args:
            cost: Weight(s) [cost]/[N m], scalar or (3,).
            name: Report label.
            servo: The damping ``kd = 2 zeta omega`` [1/s] (``kp`` unused).

        Raises:
            TaskSetupError: Invalid cost.
        """
        super().__init__(name, 3, cost, servo=servo)

    def _velocity_level(self) -> TaskSetupError:
        return TaskSetupError(f"{self.name}: the angular-momentum task has no velocity-level (IK) form; "
                              "use it in whole-body inverse dynamics")

    def compute_error(self, state: TaskState) -> np.ndarray:
        """No configuration error (raises).

        Raises:
            TaskSetupError: Always (velocity level).
        """
        raise self._velocity_level()

    def compute_jacobian(self, state: TaskState) -> np.ndarray:
        """No IK Jacobian (raises).

        Raises:
            TaskSetupError: Always (velocity level).
        """
        raise self._velocity_level()

    def jacobian_and_drift(self, state: DynamicsState) -> tuple[np.ndarray, np.ndarray]:
        """``(A_g[3:], dA_g[3:] v)``."""
        return state.centroidal_map()[3:], state.centroidal_drift()[3:]

    def desired_acceleration(self, state: DynamicsState, J: np.ndarray) -> np.ndarray:
        """``-kd h`` (3,) [N m]."""
        return -self._kd * (J @ state.v)

    def write_acceleration_rows(self, state: DynamicsState, W_t: np.ndarray, r_t: np.ndarray) -> None:
        """Fast path of ``Task.write_acceleration_rows``: ``h`` read from the state, not recomputed."""
        np.multiply(self._weights()[0], state.centroidal_map()[3:], out=W_t)
        np.multiply(state.angular_momentum(), -self._kd, out=r_t)
        r_t -= state.centroidal_drift()[3:]
        r_t *= self._cost

    def residual(self, state: TaskState) -> TaskResidual:
        """A damper has no target: zero deviation."""
        return TaskResidual(deviation=0.0)
