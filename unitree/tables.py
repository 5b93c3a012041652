"""Motor tables of Unitree's ``unitree_hg`` robots, as data: which joint each motor slot drives.

A table is the one place that knows a robot's motor order; everything else (the DDS interface,
the bridge, the motor map) is generic over it. The G1's tables were checked against Unitree's own
code and documents: ``G1JointIndex`` in unitree_sdk2 ``example/g1/low_level/g1_ankle_swing_example.cpp``
and unitree_sdk2_python ``example/g1/low_level/g1_low_level_example.py``, and unitree_mujoco's
``unitree_robots/g1/g1_joint_index_dds.md`` (29- and 23-dof versions; ``g1_29dof.xml`` lists its
motors in the same order). Every ankle (and the 29-dof waist) is in pitch/roll ("PR") order, as
``LowCmd_.mode_pr = 0`` commands them.

- 29-dof G1: left leg 0-5, right leg 6-11, waist yaw/roll/pitch 12-14, left arm 15-21 (shoulder
  pitch/roll/yaw, elbow, wrist roll/pitch/yaw), right arm 22-28.
- 23-dof G1: legs 0-11 as above, waist yaw 12 ("TORSO"), left arm 13-17 (shoulder pitch/roll/yaw,
  elbow, wrist roll: Unitree's "ELBOW_ROLL"), right arm 18-22.

Command ranges (``kp_max``, ``kd_max``, ``dq_max``): what the MuJoCo bridge accepts of a LowCmd's
gains and velocity targets (it clamps beyond them and counts it; position targets and feed-forward
torques are clamped to the model's joint ranges and torque limits). They are mbctl's bounds, not
Unitree's: Unitree publishes no gain range for the G1's motor firmware that this project could cite.
They are chosen wide (a motor at ``kp_max`` reaches the G1's largest torque limit, 139 N m, 0.14 rad
from its target; at ``kd_max`` 1.4 rad/s from it) and measured safe for the simulated plant: every
motor at both bounds with targets at its joint range's ends and full torque for 2 s stays finite
(peak acceleration 1.3e4, below the bridge's divergence bound 1e5), while kp = 1e30 diverged at once.

The IMU in ``LowState.imu_state`` is the pelvis IMU on both (unitree_sdk2's G1 examples read the
torso IMU from ``rt/secondary_imu``); in the Menagerie model it is the site ``imu_in_pelvis``.
"""

from __future__ import annotations

from dataclasses import dataclass

from mbctl.robots.g1 import G1_IMU
from mbctl.robots.interface import ImuSpec

_LEGS = (
    "left_hip_pitch_joint", "left_hip_roll_joint", "left_hip_yaw_joint", "left_knee_joint",
    "left_ankle_pitch_joint", "left_ankle_roll_joint",
    "right_hip_pitch_joint", "right_hip_roll_joint", "right_hip_yaw_joint", "right_knee_joint",
    "right_ankle_pitch_joint", "right_ankle_roll_joint",
)


def _arm(side: str, wrist: tuple[str, ...]) -> tuple[str, ...]:
    joints = ("shoulder_pitch", "shoulder_roll", "shoulder_yaw", "elbow", *wrist)
    return tuple(f"{side}_{j}_joint" for j in joints)


#: The largest position gain [N m/rad] a bridge applies (see the module docstring).
KP_MAX = 1000.0
#: The largest damping gain [N m s/rad] a bridge applies.
KD_MAX = 100.0
#: The largest magnitude [rad/s] of a velocity target a bridge applies.
DQ_MAX = 30.0


@dataclass(frozen=True)
class MotorTable:
    """One ``unitree_hg`` robot's motors: the joint each slot drives, in slot order, and its IMU.

    Attributes:
        name: What the table is for (in messages), e.g. "G1 29-dof".
        joints: Joint name (the model's) of motor 0, 1, ...; the slots above ``len(joints)`` are unused.
        imu: The IMU whose sample LowState carries.
        kp_max: Largest position gain [N m/rad] a bridge applies (mbctl's bound: module docstring).
        kd_max: Largest damping gain [N m s/rad] a bridge applies.
        dq_max: Largest magnitude [rad/s] of a velocity target a bridge applies.
    """

    name: str
    joints: tuple[str, ...]
    imu: ImuSpec
    kp_max: float = KP_MAX
    kd_max: float = KD_MAX
    dq_max: float = DQ_MAX

    @property
    def n(self) -> int:
        """Number of motors."""
        return len(self.joints)


#: The 29-dof G1 (the Menagerie model's actuated joints).
G1_29DOF = MotorTable(
    "G1 29-dof",
    _LEGS + ("waist_yaw_joint", "waist_roll_joint", "waist_pitch_joint")
    + _arm("left", ("wrist_roll", "wrist_pitch", "wrist_yaw"))
    + _arm("right", ("wrist_roll", "wrist_pitch", "wrist_yaw")),
    G1_IMU,
)

#: The 23-dof G1 (no waist roll/pitch, one wrist joint per arm).
G1_23DOF = MotorTable(
    "G1 23-dof",
    _LEGS + ("waist_yaw_joint",) + _arm("left", ("wrist_roll",)) + _arm("right", ("wrist_roll",)),
    G1_IMU,
)

#: Menagerie joint name of each 29-dof G1 motor, by motor index (Unitree's G1JointIndex order).
G1_MOTOR_JOINTS: tuple[str, ...] = G1_29DOF.joints

#: Every table, by a short name (``--motor-table``).
TABLES = {"g1-29dof": G1_29DOF, "g1-23dof": G1_23DOF}
