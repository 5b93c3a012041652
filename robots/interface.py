"""The robot API controllers are written against: read state, send a command, keep time.

It lives in robots/ (not sim/) because control/ never imports sim/. The simulator implements
it, and so does the Unitree G1 over DDS (:class:`mbctl.hardware.UnitreeG1`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import NamedTuple, Protocol, runtime_checkable

import numpy as np

from mbctl.robots.commands import Command
from mbctl.robots.model_pair import Robot
from mbctl.robots.plant_report import PlantReport

#: Names of the state fields a robot does not measure and an estimator provides.
BASE_POSITION = "base_position"
BASE_LINEAR_VELOCITY = "base_linear_velocity"


class RobotState(NamedTuple):
    """Measured state in Pinocchio's convention.

    Attributes:
        q: Configuration (nq,); free-flyer quaternion (x, y, z, w). Read-only copy.
        v: Velocity (nv,); free-flyer linear velocity in the base frame. Read-only copy.
        time_s: Time of the measurement [s].
        estimated: The fields estimated rather than measured (e.g. :data:`BASE_POSITION`,
            :data:`BASE_LINEAR_VELOCITY` on a real robot); empty when the plant gives them all.
        tick: The plant's own count of the measurement, for aligning a run with the plant's logs
            (the simulator's physics steps, a robot's LowState tick); -1 where the plant has none.
    """

    q: np.ndarray
    v: np.ndarray
    time_s: float
    estimated: tuple[str, ...] = ()
    tick: int = -1


@dataclass(frozen=True)
class ImuSpec:
    """Where a robot's IMU is in its model: the site and the names of its two sensors.

    Attributes:
        site: The IMU's site (its frame I).
        gyro: The gyro sensor's name (angular velocity of I in I).
        accelerometer: The accelerometer's name (specific force in I).
    """

    site: str
    gyro: str
    accelerometer: str


class ImuReading(NamedTuple):
    """One IMU sample, in the IMU's frame I.

    Attributes:
        quat_wxyz: Orientation of I in the world W, quaternion (w, x, y, z) (4,).
        gyro_I: Angular velocity of I in I (3,) [rad/s].
        accel_I: Specific force (acceleration minus gravity) in I (3,) [m/s^2].
    """

    quat_wxyz: np.ndarray
    gyro_I: np.ndarray
    accel_I: np.ndarray


class Proprioception(NamedTuple):
    """What a legged robot measures of itself each cycle: encoders and IMU, no base position.

    Attributes:
        time_s: Time of the measurement [s].
        q_joints: Joint positions (nq - 7,) [rad], the robot's joint order (q without the base).
        v_joints: Joint velocities (nv - 6,) [rad/s].
        imu: The IMU sample.
    """

    time_s: float
    q_joints: np.ndarray
    v_joints: np.ndarray
    imu: ImuReading


@runtime_checkable
class BaseStateEstimator(Protocol):
    """Estimates a floating base's state from proprioception (given to a plant by the job).

    A robot interface calls ``reset`` with its first reading and ``update`` every cycle; it never
    needs to know how the estimate is made (the estimators live in ``control/estimation``).
    """

    @property
    def estimated(self) -> tuple[str, ...]:
        """The state fields the estimate provides that the readings do not measure."""

    def reset(self, reading: Proprioception) -> None:
        """Start from ``reading`` (the robot at rest on its feet)."""

    def update(self, reading: Proprioception) -> tuple[np.ndarray, np.ndarray]:
        """The base's q (7,) [p_WB, quat_xyzw] and v (6,) [linear, angular, in the base frame]."""


@runtime_checkable
class RobotInterface(Protocol):
    """A robot that can be read and commanded at a fixed control period: the plant contract.

    Every plant (the simulator, the simulator behind a link model, a robot over DDS) implements
    it, and the jobs and the control loop use nothing else:

    - **Lifecycle** (as ros2_control's hardware components): ``open()`` activates the plant (a
      robot: connects and reads a valid state; a simulator is ready from construction) and
      returns it; ``close()`` deactivates it, leaving the robot safe (over DDS: the damping
      command), and is idempotent. A plant is a context manager doing both.
    - **The end of a loop**: ``stop()`` says the loop is over; from then until ``close()`` the
      plant keeps the robot safe by itself (over DDS: the damping command every period, from a
      thread, while the job writes its report and plots; a simulator has nothing to do). A new
      command resumes. ``control.loop.run`` calls it whenever its loop ends, however it ends.
    - **The cycle**: ``read_state()``, ``send(command)``, ``sync()``; commands are bound by the
      one :class:`~mbctl.robots.command_binding.CommandBinder`, so a bad command gets the same error
      on every plant.
    - **The report**: ``report()`` gives a :class:`~mbctl.robots.plant_report.PlantReport`, the
      same typed fields whichever plant produced it. Each state carries the plant's ``tick``.
    """

    @property
    def robot(self) -> Robot:
        """The robot's model pair."""

    @property
    def control_period_s(self) -> float:
        """Duration [s] of one control cycle (``sync`` advances by this much)."""

    @property
    def time_s(self) -> float:
        """Current time [s]."""

    def read_state(self) -> RobotState:
        """The latest measured state."""

    def send(self, command: Command) -> None:
        """Apply a command; it holds until the next one."""

    def sync(self) -> None:
        """Wait for the next control cycle (a simulator steps the physics for one period)."""

    def open(self) -> RobotInterface:
        """Activate the plant (idempotent) and return it."""

    def stop(self) -> None:
        """The loop is over: keep the robot safe until ``close()`` (or a new command) (idempotent)."""

    def close(self) -> None:
        """Deactivate the plant, leaving the robot safe (idempotent)."""

    def report(self) -> PlantReport:
        """The plant's typed report on the run so far."""

    def position_gains(self) -> Mapping[str, tuple[float, float]]:
        """The (kp [N m/rad], kd [N m s/rad]) the plant applies to a position target, by joint name."""

    def __enter__(self) -> RobotInterface:
        """``open()``."""

    def __exit__(self, *exc: object) -> None:
        """``close()``."""
