"""mbctl.control: feedback laws and the control loop, written against the robot API (never imports mbctl.sim).

Subpackages, each with its own public names: :mod:`mbctl.control.tasks` (the task layer),
:mod:`mbctl.control.ik` (differential IK) and :mod:`mbctl.control.wbc` (whole-body inverse
dynamics), the two peers above the task layer.
"""

from mbctl.control.computed_torque import ComputedTorque
from mbctl.control.controller import (
    Controller,
    JointMap,
    JointReference,
    TaskReference,
    TorqueSaturation,
    joint_reference,
    task_reference,
)
from mbctl.control.exceptions import (
    ControlError,
    ControllerSetupError,
    GainsError,
    IKInfeasible,
    IKSetupError,
    KinematicsError,
    ReferenceMismatch,
    SingularJacobian,
    TaskSetupError,
    UnreachableTarget,
    WBCInfeasible,
    WBCSetupError,
)
from mbctl.control.gains import PDGains, gains_from_frequency
from mbctl.control.loop import ColumnStats, RunLog, RunStats, presample, run
from mbctl.control.pd import JointPD
from mbctl.control.pd_gravity import PDGravity
from mbctl.control.position_pd import PositionTargetPD
from mbctl.control.task_space import TaskSpaceComputedTorque

__all__ = [
    "ColumnStats",
    "ComputedTorque",
    "ControlError",
    "Controller",
    "ControllerSetupError",
    "GainsError",
    "IKInfeasible",
    "IKSetupError",
    "JointMap",
    "JointPD",
    "JointReference",
    "KinematicsError",
    "PDGains",
    "PDGravity",
    "PositionTargetPD",
    "ReferenceMismatch",
    "RunLog",
    "RunStats",
    "SingularJacobian",
    "TaskReference",
    "TaskSetupError",
    "TaskSpaceComputedTorque",
    "TorqueSaturation",
    "UnreachableTarget",
    "WBCInfeasible",
    "WBCSetupError",
    "gains_from_frequency",
    "joint_reference",
    "presample",
    "run",
    "task_reference",
]
