"""mbctl.control: controllers, kinematics and inverse kinematics (never imports mbctl.sim)."""

from mbctl.control.exceptions import (
    ControlError,
    IKInfeasible,
    IKSetupError,
    KinematicsError,
    UnreachableTarget,
)

# The IK names are mbctl.control.ik's; re-exported here as one list (no second copy).
from mbctl.control.ik import *  # noqa: E402, F403
from mbctl.control.ik import __all__ as _IK_ALL  # noqa: E402

__all__ = [
    "ControlError",
    "IKInfeasible",
    "IKSetupError",
    "KinematicsError",
    "UnreachableTarget",
    *_IK_ALL,
]

# Controllers, gains and the control loop (appended; the IK names above are another module family).
from mbctl.control.computed_torque import ComputedTorque  # noqa: E402
from mbctl.control.controller import (  # noqa: E402
    Controller,
    JointMap,
    JointReference,
    TaskReference,
    TorqueSaturation,
    joint_reference,
    task_reference,
)
from mbctl.control.exceptions import ControllerSetupError, GainsError, ReferenceMismatch  # noqa: E402
from mbctl.control.gains import PDGains, gains_from_frequency  # noqa: E402
from mbctl.control.loop import RunLog, presample, run  # noqa: E402
from mbctl.control.pd import JointPD  # noqa: E402
from mbctl.control.pd_gravity import PDGravity  # noqa: E402
from mbctl.control.position_pd import PositionTargetPD  # noqa: E402
from mbctl.control.task_space import TaskSpaceComputedTorque  # noqa: E402

__all__ += [
    "ComputedTorque",
    "Controller",
    "ControllerSetupError",
    "GainsError",
    "JointMap",
    "JointPD",
    "JointReference",
    "PDGains",
    "PDGravity",
    "PositionTargetPD",
    "ReferenceMismatch",
    "RunLog",
    "TaskReference",
    "TaskSpaceComputedTorque",
    "TorqueSaturation",
    "gains_from_frequency",
    "joint_reference",
    "presample",
    "run",
    "task_reference",
]
