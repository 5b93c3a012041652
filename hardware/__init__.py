"""Real robots behind the robot API: the Unitree G1 over its low-level DDS (a plant beside sim/).

It imports robots/ only, never sim/ or control/: the base-state estimator is given by the job.
"""

from mbctl.hardware.exceptions import DryRunError, HardwareError, JointOutOfLimits, LinkLost, NoRobotError
from mbctl.hardware.motor_commands import MotorCommandWriter, MotorGains, default_damping
from mbctl.hardware.unitree_g1 import DdsOptions, UnitreeG1

__all__ = [
    "DdsOptions",
    "DryRunError",
    "HardwareError",
    "JointOutOfLimits",
    "LinkLost",
    "MotorCommandWriter",
    "MotorGains",
    "NoRobotError",
    "UnitreeG1",
    "default_damping",
]
