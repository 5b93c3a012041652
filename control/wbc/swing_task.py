"""The swing foot's task: a frame pose task with the swing path's yaw rate and acceleration fed forward."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from mbctl.control.tasks.base import AccelerationGains
from mbctl.control.tasks.frame_pose import FramePoseTask
from mbctl.control.tasks.state import DynamicsState
from mbctl.planners.swing import SwingSample


class SwingFootTask(FramePoseTask):
    """The swing foot's pose with its turning fed forward: a frame pose task plus a yaw rate and acceleration.

    ``a_des = a_ref + kp log6(X_FT) + kd (v_ref - J_F v)`` in F, with ``v_ref = R_FW [v_W; w_W]`` and
    ``a_ref = R_FW [a_W; alpha_W]``, ``w_W = (0, 0, yaw rate)``, ``alpha_W = (0, 0, yaw acceleration)``
    (the frame pose task's angular references are zero, so a turning foot would lag).
    """

    def __init__(self, frame: str, model: pin.Model, cost: float, servo: AccelerationGains,
                 orientation_cost: float | None = None):
        super().__init__(frame, model, cost, cost if orientation_cost is None else orientation_cost,
                         name=f"{frame} swing", servo=servo)
        self.yaw_rate_rad_s = 0.0
        self.yaw_acceleration_rad_s2 = 0.0
        self._v_ref_F, self._a_ref_F = np.zeros(6), np.zeros(6)

    def set_swing_target(self, sample: SwingSample) -> None:
        """The target pose, velocity and acceleration from a swing path sample (a level foot at its yaw)."""
        X = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, sample.yaw_rad), sample.position)
        self.set_target(X, sample.velocity, sample.acceleration)
        self.yaw_rate_rad_s = sample.yaw_rate_rad_s
        self.yaw_acceleration_rad_s2 = sample.yaw_acceleration_rad_s2

    def desired_acceleration(self, state: DynamicsState, J: np.ndarray) -> np.ndarray:
        """``a_ref + kp log6(X_FT) + kd (v_ref - J_F v)`` (6,) in F, with the yaw references."""
        R_FW = state.frame_pose(self.frame_id).rotation.T
        v_ref, a_ref = self._v_ref_F, self._a_ref_F  # written in place (no concatenation per cycle)
        np.matmul(R_FW, self.v_ref_W, out=v_ref[:3])
        np.multiply(R_FW[:, 2], self.yaw_rate_rad_s, out=v_ref[3:])
        np.matmul(R_FW, self.a_ref_W, out=a_ref[:3])
        np.multiply(R_FW[:, 2], self.yaw_acceleration_rad_s2, out=a_ref[3:])
        return a_ref + self._kp * self.compute_error(state) + self._kd * (v_ref - J @ state.v)
