"""A frame's pose relative to another frame: ``e = log6(X_TF)`` (6,) [m, rad] (mink's ``RelativeFrameTask``).

Notation (Drake monograms): F the task frame, R the reference (root) frame, T the target frame
given in R: ``X_RF = X_WR^-1 X_WF``, ``X_TF = X_RT^-1 X_RF``. Both F and R may move (e.g. a hand
held in front of the torso while the torso bends).

Velocity level: the twist of F relative to R, in F, is ``J_rel = J_F - Ad(X_FR) J_R`` with the
body (LOCAL) Jacobians of F and R, so ``J_e = Jlog6(X_TF) J_rel`` (Pinocchio's exact ``Jlog6``).
There is no acceleration-level form (the whole-body controller takes world-frame tasks).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from mbctl.control.tasks.base import dot_into
from mbctl.control.tasks.frame import FrameTask, pose_cost
from mbctl.control.tasks.residuals import TaskResidual
from mbctl.control.tasks.state import TaskState
from mbctl.robots.exceptions import UnknownNameError


class RelativeFrameTask(FrameTask):
    """Pose of F in R: ``e = log6(X_TF)`` (6,) [m, rad] in F, ``J_e = Jlog6(X_TF) (J_F - Ad(X_FR) J_R)``.

    Attributes:
        reference: The reference frame's name.
        reference_id: Its Pinocchio frame id.
    """

    def __init__(
        self,
        frame: str,
        reference: str,
        model: TaskState | pin.Model,
        position_cost: npt.ArrayLike = 1.0,
        orientation_cost: npt.ArrayLike = 1.0,
        gain: float = 1.0,
        lm_damping: float = 0.0,
        name: str | None = None,
    ):
        """Create the task (set a target, a pose in the reference frame, before solving).

        Args:
            frame: Pinocchio frame name of F.
            reference: Pinocchio frame name of R.
            model: Pinocchio model or task state.
            position_cost: Weight(s) on the translation error [cost]/[m], scalar or (3,).
            orientation_cost: Weight(s) on the rotation error [cost]/[rad], scalar or (3,).
            gain: Fraction of the error corrected per step, in [0, 1].
            lm_damping: Levenberg-Marquardt scale [-].
            name: Report label (default: "<frame> in <reference>").

        Raises:
            UnknownNameError: No frame called ``frame`` or ``reference``.
            TaskSetupError: Invalid costs, gain or damping.
        """
        super().__init__(name or f"{frame} in {reference}", frame, model, 6,
                         pose_cost(frame, position_cost, orientation_cost), gain, lm_damping, None)
        pin_model = model.model if isinstance(model, TaskState) else model
        if not pin_model.existFrame(reference):
            raise UnknownNameError("frame", reference, [f.name for f in pin_model.frames])
        self.reference = reference
        self.reference_id = pin_model.getFrameId(reference)

    def set_target(self, transform_target_to_reference: pin.SE3, v: npt.ArrayLike = (0.0, 0.0, 0.0),
                   a: npt.ArrayLike = (0.0, 0.0, 0.0)) -> None:
        """Set the target pose ``X_RT`` (in the reference frame); ``v`` and ``a`` are unused.

        Raises:
            TaskSetupError: A velocity or acceleration that is not 3 finite numbers.
        """
        self._set_pose(transform_target_to_reference, v, a)

    def set_target_from_state(self, state: TaskState) -> None:
        """Set the target to F's current pose in R."""
        self.set_target(self._X_RF(state))

    def _X_RF(self, state: TaskState) -> pin.SE3:
        return state.oMf[self.reference_id].actInv(state.oMf[self.frame_id])

    def _X_TF(self, state: TaskState) -> pin.SE3:
        if self._X_TW is None:  # here X_TR: the target is stored in the reference frame
            raise self._no_target()
        return self._X_TW * self._X_RF(state)

    def _relative_jacobian(self, state: TaskState) -> np.ndarray:
        """``J_F - Ad(X_FR) J_R`` (6, nv): F's twist relative to R, in F."""
        X_FR = self._X_RF(state).inverse()
        return state.frame_jacobian(self.frame_id) - X_FR.action @ state.frame_jacobian(self.reference_id)

    def compute_error(self, state: TaskState) -> np.ndarray:
        """``log6(X_TF)`` (6,) [m, rad]."""
        return pin.log6(self._X_TF(state)).vector

    def compute_jacobian(self, state: TaskState) -> np.ndarray:
        """``Jlog6(X_TF) J_rel`` (6, nv)."""
        return pin.Jlog6(self._X_TF(state)) @ self._relative_jacobian(state)

    def write_velocity_rows(self, state: TaskState, J_out: np.ndarray, e_out: np.ndarray) -> None:
        """The active rows of ``(J_e, e)``."""
        X_TF = self._X_TF(state)
        rows = self.active_index()
        dot_into(pin.Jlog6(X_TF)[rows], self._relative_jacobian(state), J_out)
        e_out[:] = pin.log6(X_TF).vector[rows]

    def residual(self, state: TaskState) -> TaskResidual:
        """Distance [m] and rotation angle [rad] to the target in R; a part with zero cost is left out."""
        X_TF = self._X_TF(state)
        position = float(np.linalg.norm(X_TF.translation)) if np.any(self.cost[:3] > 0.0) else None
        angle = float(np.linalg.norm(pin.log3(X_TF.rotation))) if np.any(self.cost[3:] > 0.0) else None
        return TaskResidual(position_m=position, orientation_rad=angle)
