"""mbctl.control: controllers, kinematics and inverse kinematics (never imports mbctl.sim)."""

from mbctl.control.exceptions import (
    ControlError,
    IKInfeasible,
    IKSetupError,
    KinematicsError,
    UnreachableTarget,
)
from mbctl.control.ik_limits import (
    BoxLimit,
    Constraint,
    FloatingBaseVelocityLimit,
    JointPositionLimit,
    JointVelocityLimit,
    Limit,
)
from mbctl.control.ik_solve import DiffIK, IKResult, IKStep, solve_ik
from mbctl.control.ik_state import IKState
from mbctl.control.ik_tasks import (
    ComTask,
    DampingTask,
    FrameOrientationTask,
    FramePoseTask,
    FramePositionTask,
    PostureTask,
    Task,
)
from mbctl.control.two_link import (
    ElbowBranch,
    IterativeIKResult,
    TwoLinkArm,
    Workspace,
    dls_ik,
    pinv_ik,
    plot_workspace,
)

__all__ = [
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
    "PostureTask",
    "Task",
    "TwoLinkArm",
    "UnreachableTarget",
    "Workspace",
    "dls_ik",
    "pinv_ik",
    "plot_workspace",
    "solve_ik",
]
