"""The swing foot's task: a frame pose task whose target turns with the swing path's yaw."""

from __future__ import annotations

import pinocchio as pin

from mbctl.control.tasks.base import AccelerationGains
from mbctl.control.tasks.frame_pose import FramePoseTask
from mbctl.planners.swing import SwingSample


class SwingFootTask(FramePoseTask):
    """The swing foot's pose, its yaw rate and acceleration fed forward as the angular reference.

    ``a_des = a_ref + kp log6(X_FT) + kd (v_ref - J_F v)`` in F (the frame pose task's law), with
    ``v_ref = R_FW [v_W; w_W]`` and ``a_ref = R_FW [a_W; alpha_W]``, ``w_W = (0, 0, yaw rate)``,
    ``alpha_W = (0, 0, yaw acceleration)`` (without them a turning foot would lag).
    """

    def __init__(self, frame: str, model: pin.Model, cost: float, servo: AccelerationGains,
                 orientation_cost: float | None = None):
        super().__init__(frame, model, cost, cost if orientation_cost is None else orientation_cost,
                         name=f"{frame} swing", servo=servo)

    @property
    def yaw_rate_rad_s(self) -> float:
        """The target's yaw rate [rad/s] (about W's z)."""
        return float(self.w_ref_W[2])

    @property
    def yaw_acceleration_rad_s2(self) -> float:
        """The target's yaw acceleration [rad/s^2] (about W's z)."""
        return float(self.alpha_ref_W[2])

    def set_swing_target(self, sample: SwingSample) -> None:
        """The target pose, velocity and acceleration from a swing path sample (a level foot at its yaw)."""
        X = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, sample.yaw_rad), sample.position)
        self.set_target(X, sample.velocity, sample.acceleration)
        self.set_angular_reference((0.0, 0.0, sample.yaw_rate_rad_s),
                                   (0.0, 0.0, sample.yaw_acceleration_rad_s2))
