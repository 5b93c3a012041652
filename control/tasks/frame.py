"""What every frame task shares: the frame, its target pose ``X_WT`` and the error pose ``X_TF``.

Notation (Drake monograms): W world, F the task frame, T the target frame;
``X_TF = X_WT^-1 X_WF``. Velocity and acceleration references of the target are given in W.
"""

from __future__ import annotations

from math import isfinite

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from mbctl.control.exceptions import TaskSetupError
from mbctl.control.tasks.base import AccelerationGains, Task, cost_vector
from mbctl.control.tasks.state import TaskState
from mbctl.robots.exceptions import UnknownNameError
from mbctl.robots.fastmath import all_finite


def pin_model(state_or_model: TaskState | pin.Model) -> pin.Model:
    """The Pinocchio model of a task state, or the model itself."""
    return state_or_model.model if isinstance(state_or_model, TaskState) else state_or_model


_PLAIN = (list, tuple)
_NUMBERS = (float, int)


def world_vector(value: npt.ArrayLike, task: str, what: str) -> np.ndarray:
    """``value`` as a finite (3,) vector in W (a copy): ``what`` of the task named ``task``.

    Raises:
        TaskSetupError: Not 3 finite numbers (the message names the task and ``what``).
    """
    if value.__class__ in _PLAIN and len(value) == 3:  # type: ignore[arg-type]  # 3 numbers, every cycle
        x, y, z = value  # type: ignore[misc]
        if x.__class__ in _NUMBERS and y.__class__ in _NUMBERS and z.__class__ in _NUMBERS \
                and isfinite(x) and isfinite(y) and isfinite(z):  # checked before converting: ~0.3 us less
            return np.array(value, dtype=float)
    arr = np.array(value, dtype=float)
    if arr.shape != (3,) or not all_finite(arr.tolist()):  # targets are set every cycle: no label built
        raise TaskSetupError(f"{task}: {what} must be a finite (3,) vector in the world frame; got {value!r}")
    return arr


def pose_cost(frame: str, position_cost: npt.ArrayLike, orientation_cost: npt.ArrayLike) -> np.ndarray:
    """The (6,) cost of a pose task: position [cost]/[m] then orientation [cost]/[rad], each scalar or (3,).

    Raises:
        TaskSetupError: A negative, non-finite or misshaped cost (the message names which).
    """
    return np.concatenate([cost_vector(position_cost, 3, frame, "position_cost"),
                           cost_vector(orientation_cost, 3, frame, "orientation_cost")])


class FrameTask(Task):
    """A task on the pose of one Pinocchio frame F against a target pose ``X_WT``.

    Attributes:
        frame: Frame name.
        frame_id: Pinocchio frame id.
        v_ref_W: Target linear velocity (3,) [m/s] in W (acceleration level).
        a_ref_W: Target linear acceleration (3,) [m/s^2] in W (acceleration level).
    """

    def __init__(self, name: str, frame: str, state_or_model: TaskState | pin.Model, k: int,
                 cost: npt.ArrayLike, gain: float, lm_damping: float, servo: AccelerationGains | None):
        super().__init__(name, k, cost, gain, lm_damping, servo)
        model = pin_model(state_or_model)
        if not model.existFrame(frame):
            raise UnknownNameError("frame", frame, [f.name for f in model.frames])
        self.frame = frame
        self.frame_id = model.getFrameId(frame)
        self._X_WT: pin.SE3 | None = None
        self._X_TW: pin.SE3 | None = None
        self._R_TW = np.eye(3)
        self.v_ref_W = np.zeros(3)
        self.a_ref_W = np.zeros(3)

    def _set_pose(self, X_WT: pin.SE3, v: npt.ArrayLike, a: npt.ArrayLike) -> None:
        v_W = world_vector(v, self.name, "target velocity [m/s]")
        a_W = world_vector(a, self.name, "target acceleration [m/s^2]")
        self._X_WT = pin.SE3(X_WT)
        self._X_TW = self._X_WT.inverse()
        self._R_TW = self._X_TW.rotation  # a numpy copy, made once (SE3.rotation copies per read)
        self.v_ref_W[:] = v_W
        self.a_ref_W[:] = a_W

    def set_target(self, transform_target_to_world: pin.SE3, v: npt.ArrayLike = (0.0, 0.0, 0.0),
                   a: npt.ArrayLike = (0.0, 0.0, 0.0)) -> None:
        """Set the target pose ``X_WT`` and its linear velocity [m/s] and acceleration [m/s^2] in W.

        The angular reference is zero velocity and acceleration.

        Raises:
            TaskSetupError: A velocity or acceleration that is not 3 finite numbers.
        """
        self._set_pose(transform_target_to_world, v, a)

    def set_target_from_state(self, state: TaskState) -> None:
        """Set the target to the frame's current pose, at rest."""
        self.set_target(state.frame_pose(self.frame_id))

    @property
    def transform_target_to_world(self) -> pin.SE3:
        """Target pose ``X_WT``.

        Raises:
            TaskSetupError: No target set yet.
        """
        if self._X_WT is None:
            raise self._no_target()
        return self._X_WT

    def _X_TF(self, state: TaskState) -> pin.SE3:
        """``X_TF = X_WT^-1 X_WF`` at ``state``.

        Raises:
            TaskSetupError: No target set yet.
        """
        if self._X_TW is None:
            raise self._no_target()
        return self._X_TW * state.oMf[self.frame_id]
