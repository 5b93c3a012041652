"""What a legged robot measures of itself, read from the MuJoCo plant: encoders and an IMU.

The IMU's orientation is its site's frame (a real IMU's orientation filter; exact here), its
angular velocity and specific force come from the model's gyro and accelerometer sensors. MuJoCo
does not apply a sensor's ``noise`` attribute; :class:`ImuNoise` adds white noise scaled from it,
so ``--imu-noise 1`` is the noise the model declares.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from mbctl.robots.interface import ImuReading, ImuSpec, Proprioception
from mbctl.sim.exceptions import SimError
from mbctl.sim.simulator import Simulator


@dataclass(frozen=True)
class ImuNoise:
    """White noise on the gyro and accelerometer, as a multiple of the model's declared noise.

    Attributes:
        scale: 0 for none, 1 for the sensors' ``noise`` attribute as standard deviation.
        gyro_rad_s: The gyro's declared noise [rad/s] (from the model).
        accel_m_s2: The accelerometer's declared noise [m/s^2] (from the model).
    """

    scale: float = 0.0
    gyro_rad_s: float = 0.0
    accel_m_s2: float = 0.0

    def __post_init__(self) -> None:
        if not (np.isfinite(self.scale) and self.scale >= 0):
            raise SimError(f"imu_noise must be a finite factor >= 0; got {self.scale}")


class ImuReader:
    """Reads a robot's IMU and joints from a Simulator (ids resolved once).

    Args:
        sim: The plant.
        spec: The IMU's site and sensor names.
        noise_scale: Multiple of the sensors' declared noise to add (0: none).
        seed: Seed of the noise.

    Raises:
        UnknownNameError: A site or sensor the model lacks.
        SimError: A robot without a floating base, or a negative noise scale.
    """

    def __init__(self, sim: Simulator, spec: ImuSpec, noise_scale: float = 0.0, seed: int = 0):
        robot = sim.robot
        if not robot.has_floating_base:
            raise SimError(f"{robot.name} has a fixed base: it has no IMU state to report")
        self._sim = sim
        self._site = robot.site_id(spec.site)
        gyro, accel = robot.sensor(spec.gyro), robot.sensor(spec.accelerometer)
        self._gyro, self._accel = gyro.data_slice, accel.data_slice
        m = sim.model
        self.noise = ImuNoise(noise_scale, float(m.sensor_noise[robot.mj_model.sensor(spec.gyro).id]),
                              float(m.sensor_noise[robot.mj_model.sensor(spec.accelerometer).id]))
        self._rng = np.random.default_rng(seed)
        self._quat = np.empty(4)

    def imu(self, forward: bool = True) -> ImuReading:
        """The IMU now: quaternion (w, x, y, z) of its site, gyro [rad/s], specific force [m/s^2].

        Args:
            forward: Bring the data up to date first; False reads it as it is (between
                ``Simulator.step_begin`` and after ``step_end``, it holds the step's start state).
        """
        sim = self._sim
        if forward:
            sim.forward()
        d = sim.data
        mujoco.mju_mat2Quat(self._quat, d.site_xmat[self._site])
        gyro = d.sensordata[self._gyro].copy()
        accel = d.sensordata[self._accel].copy()
        if self.noise.scale:
            gyro += self._rng.normal(0.0, self.noise.scale * self.noise.gyro_rad_s, 3)
            accel += self._rng.normal(0.0, self.noise.scale * self.noise.accel_m_s2, 3)
        return ImuReading(self._quat.copy(), gyro, accel)

    def at_rest(self, forward: bool = True) -> ImuReading:
        """The IMU of the robot held still (before its first command): no noise.

        Its site's orientation, no rotation, and the specific force of a body at rest, -g in the
        IMU's frame (the plant's own accelerometer would read the acceleration the uncommanded
        robot would have).

        Args:
            forward: Bring the data up to date first (see :meth:`imu`).
        """
        sim = self._sim
        if forward:
            sim.forward()
        R_WI = sim.data.site_xmat[self._site].reshape(3, 3)
        mujoco.mju_mat2Quat(self._quat, sim.data.site_xmat[self._site])
        return ImuReading(self._quat.copy(), np.zeros(3), -R_WI.T @ sim.model.opt.gravity)

    def proprioception(self, held: bool = False) -> Proprioception:
        """Joint positions and velocities (Pinocchio convention, base excluded) and the IMU.

        Args:
            held: The robot is held still (:meth:`at_rest` for the IMU).
        """
        state = self._sim.read_state()
        return Proprioception(state.time_s, state.q[7:], state.v[6:], self.at_rest() if held else self.imu())
