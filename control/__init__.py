"""mbctl.control: controllers, kinematics and inverse kinematics (never imports mbctl.sim)."""

from mbctl.control.exceptions import (
    ControlError,
    IKInfeasible,
    IKSetupError,
    KinematicsError,
    UnreachableTarget,
)
from mbctl.control.ik.backends import (
    BACKENDS,
    MinkWholeBodyIK,
    QPWholeBodyIK,
    WholeBodyIK,
    WholeBodyIKConfig,
    WholeBodyIKResult,
    make_whole_body_ik,
)
from mbctl.control.ik.limits import (
    BoxLimit,
    Constraint,
    FloatingBaseVelocityLimit,
    JointPositionLimit,
    JointVelocityLimit,
    Limit,
)
from mbctl.control.ik.solve import DiffIK, IKResult, IKStep, solve_ik
from mbctl.control.ik.state import IKState
from mbctl.control.ik.tasks import (
    ComTask,
    DampingTask,
    FrameOrientationTask,
    FramePoseTask,
    FramePositionTask,
    PostureTask,
    Task,
)
from mbctl.control.ik.two_link import (
    ElbowBranch,
    IterativeIKResult,
    TwoLinkArm,
    Workspace,
    dls_ik,
    pinv_ik,
)

__all__ = [
    "BACKENDS",
    "BoxLimit",
    "ComTask",
    "Constraint",
    "ControlError",
    "DampingTask",
    "DiffIK",
    "ElbowBranch",
    "FloatingBaseVelocityLimit",
    "FrameOrientationTask",
    "FramePoseTask",
    "FramePositionTask",
    "IKInfeasible",
    "IKResult",
    "IKSetupError",
    "IKState",
    "IKStep",
    "IterativeIKResult",
    "JointPositionLimit",
    "JointVelocityLimit",
    "KinematicsError",
    "Limit",
    "MinkWholeBodyIK",
    "PostureTask",
    "QPWholeBodyIK",
    "Task",
    "TwoLinkArm",
    "UnreachableTarget",
    "WholeBodyIK",
    "WholeBodyIKConfig",
    "WholeBodyIKResult",
    "Workspace",
    "dls_ik",
    "pinv_ik",
    "make_whole_body_ik",
    "solve_ik",
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
