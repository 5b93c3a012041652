"""Real robots behind the robot API: Unitree's ``unitree_hg`` robots (the G1) over their low-level DDS.

A plant beside sim/: it imports robots/ and the Unitree floor (:mod:`mbctl.unitree`) only, never
sim/ or control/ (the base-state estimator is given by the job).
"""

from mbctl.hardware.dds_options import WATCHDOG_PERIODS, DdsOptions
from mbctl.hardware.exceptions import DryRunError, HardwareError, JointOutOfLimits, LinkLost, NoRobotError
from mbctl.hardware.motor_commands import MotorCommandWriter, MotorGains, MotorPolicy, default_damping
from mbctl.hardware.unitree_hg import UnitreeG1, UnitreeHG

__all__ = [
    "WATCHDOG_PERIODS",
    "DdsOptions",
    "DryRunError",
    "HardwareError",
    "JointOutOfLimits",
    "LinkLost",
    "MotorCommandWriter",
    "MotorGains",
    "MotorPolicy",
    "NoRobotError",
    "UnitreeG1",
    "UnitreeHG",
    "default_damping",
]
