"""The G1's motor table and IMU: which Menagerie joint each of the 29 motor slots drives.

The table is the one place that knows the G1's motor order. It was checked against Unitree's own
code (``G1JointIndex`` in unitree_sdk2 ``example/g1/low_level/g1_ankle_swing_example.cpp`` and in
unitree_sdk2_python ``example/g1/low_level/g1_low_level_example.py``; unitree_mujoco's
``g1_29dof.xml`` lists its motors in the same order): left leg 0-5, right leg 6-11, waist 12-14,
left arm 15-21, right arm 22-28, every ankle in pitch/roll ("PR") order. The ``unitree_hg``
messages carry 35 motor slots; slots 29-34 are unused on the 29-dof G1.

:class:`MotorMap` derives, once, where each motor sits in a :class:`~mbctl.robots.model_pair.Robot`
(its q and v indices in Pinocchio's convention, its actuator, its limits), so the hot path moves
whole arrays with one fancy index.

The IMU in ``LowState.imu_state`` is the pelvis IMU (unitree_sdk2's G1 examples read the torso IMU
from ``rt/secondary_imu``); in the Menagerie model it is the site ``imu_in_pelvis`` with a gyro and
an accelerometer.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from mbctl.robots.exceptions import UnknownNameError
from mbctl.robots.model_pair import Robot
from mbctl.robots.names import ActuatorInfo
from mbctl.robots.unitree.exceptions import MotorTableError

#: Motor slots in the ``unitree_hg`` LowCmd_ / LowState_ messages.
MOTOR_SLOTS = 35

#: Menagerie joint name of each G1 motor, by motor index (Unitree's G1JointIndex order).
G1_MOTOR_JOINTS: tuple[str, ...] = (
    "left_hip_pitch_joint", "left_hip_roll_joint", "left_hip_yaw_joint", "left_knee_joint",
    "left_ankle_pitch_joint", "left_ankle_roll_joint",
    "right_hip_pitch_joint", "right_hip_roll_joint", "right_hip_yaw_joint", "right_knee_joint",
    "right_ankle_pitch_joint", "right_ankle_roll_joint",
    "waist_yaw_joint", "waist_roll_joint", "waist_pitch_joint",
    "left_shoulder_pitch_joint", "left_shoulder_roll_joint", "left_shoulder_yaw_joint",
    "left_elbow_joint", "left_wrist_roll_joint", "left_wrist_pitch_joint", "left_wrist_yaw_joint",
    "right_shoulder_pitch_joint", "right_shoulder_roll_joint", "right_shoulder_yaw_joint",
    "right_elbow_joint", "right_wrist_roll_joint", "right_wrist_pitch_joint", "right_wrist_yaw_joint",
)

#: ``LowCmd_.mode_pr``: 0 commands the ankles (and waist) as pitch/roll joints, as the Menagerie
#: model has them; 1 ("AB") commands the parallel linkage's motors directly (not modelled here).
MODE_PR = 0
#: ``MotorCmd_.mode``: 1 enables the motor, 0 leaves it free.
MOTOR_ENABLED = 1


@dataclass(frozen=True)
class ImuSpec:
    """Where the robot's IMU is in the model: its site and the names of its two sensors."""

    site: str
    gyro: str
    accelerometer: str


#: The IMU reported in the G1's LowState (the pelvis IMU).
G1_IMU = ImuSpec("imu_in_pelvis", "imu-pelvis-angular-velocity", "imu-pelvis-linear-acceleration")


def motor_index(joint: str, table: Sequence[str] = G1_MOTOR_JOINTS) -> int:
    """The motor index of Menagerie joint ``joint``.

    Raises:
        UnknownNameError: A joint the table does not drive (the message names the table's joints).
    """
    try:
        return list(table).index(joint)
    except ValueError:
        raise UnknownNameError("motor joint", joint, table) from None


def motor_joint(index: int, table: Sequence[str] = G1_MOTOR_JOINTS) -> str:
    """The Menagerie joint name of motor ``index``.

    Raises:
        UnknownNameError: An index outside 0..len(table)-1 (slots above it are unused).
    """
    if not 0 <= index < len(table):
        raise UnknownNameError("motor index", str(index), [str(i) for i in range(len(table))])
    return table[index]


@dataclass(frozen=True, eq=False)
class MotorMap:
    """Where each motor of the table sits in a robot (index arrays derived once, read-only).

    Attributes:
        joints: Joint name per motor (n,).
        idx_q: Index in q (Pinocchio convention) per motor (n,).
        idx_v: Index in v per motor (n,).
        actuator: Index in the robot's actuators (ctrl order) per motor (n,).
        q_low: Lower joint limit [rad] per motor (n,).
        q_high: Upper joint limit [rad] per motor (n,).
        tau_max: Torque limit [N m] per motor (n,): the actuator's force range (the joint's
            ``actuatorfrcrange`` in the Menagerie G1), or its ctrlrange for a motor actuator.
    """

    joints: tuple[str, ...]
    idx_q: np.ndarray
    idx_v: np.ndarray
    actuator: np.ndarray
    q_low: np.ndarray
    q_high: np.ndarray
    tau_max: np.ndarray

    @property
    def n(self) -> int:
        """Number of motors."""
        return len(self.joints)

    @classmethod
    def for_robot(cls, robot: Robot, table: Sequence[str] = G1_MOTOR_JOINTS) -> MotorMap:
        """Resolve ``table`` in ``robot``.

        Raises:
            MotorTableError: A table joint the robot lacks, an actuated joint the table lacks, or
                a motor without a finite torque limit.
        """
        table = tuple(table)
        missing = [j for j in table if j not in robot.joints]
        driven = {a.joint for a in robot.actuators.values() if a.joint}
        extra = sorted(driven - set(table))
        undriven = [j for j in table if j not in driven]
        if missing or extra or undriven:
            raise MotorTableError(
                "the robot does not match the G1 motor table: "
                + "; ".join(p for p in (
                    f"joints missing from the robot: {missing}" if missing else "",
                    f"actuated joints without a motor slot: {extra}" if extra else "",
                    f"motor joints without an actuator: {undriven}" if undriven else "") if p)
                + " (load the Menagerie G1: load_robot('g1'))")
        layouts = [robot.joint(j) for j in table]
        acts = [robot.actuator_for_joint(j) for j in table]
        low = robot.pin_model.lowerPositionLimit
        high = robot.pin_model.upperPositionLimit
        tau_max = np.array([_torque_limit(a) for a in acts])
        if not np.all(np.isfinite(tau_max)):
            bad = [t for t, x in zip(table, tau_max, strict=True) if not np.isfinite(x)]
            raise MotorTableError(f"motors without a torque limit in the model: {bad}")
        arrays = [np.array([j.idx_q for j in layouts]), np.array([j.idx_v for j in layouts]),
                  np.array([a.index for a in acts]),
                  np.array([low[j.idx_q] for j in layouts]), np.array([high[j.idx_q] for j in layouts]),
                  tau_max]
        for arr in arrays:
            arr.setflags(write=False)
        return cls(table, *arrays)


def _torque_limit(actuator: ActuatorInfo) -> float:
    """The largest |torque| [N m] an actuator can apply: its force range, else a motor's ctrlrange."""
    lo, hi = actuator.force_range
    if not (np.isfinite(lo) and np.isfinite(hi)) and actuator.kind == "torque":
        lo, hi = (actuator.gear * x for x in actuator.ctrl_range)
    return float(min(abs(lo), abs(hi)))
