"""Differential inverse kinematics: state, tasks, limits, the QP, whole-body backends, 2-link IK."""

from mbctl.control.ik.backends import (
    BACKENDS,
    MinkWholeBodyIK,
    QPWholeBodyIK,
    WholeBodyIK,
    WholeBodyIKConfig,
    WholeBodyIKResult,
    make_whole_body_ik,
    mujoco_frame_type,
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
    "DampingTask",
    "DiffIK",
    "ElbowBranch",
    "FloatingBaseVelocityLimit",
    "FrameOrientationTask",
    "FramePoseTask",
    "FramePositionTask",
    "IKResult",
    "IKState",
    "IKStep",
    "IterativeIKResult",
    "JointPositionLimit",
    "JointVelocityLimit",
    "Limit",
    "MinkWholeBodyIK",
    "PostureTask",
    "QPWholeBodyIK",
    "Task",
    "TwoLinkArm",
    "WholeBodyIK",
    "WholeBodyIKConfig",
    "WholeBodyIKResult",
    "Workspace",
    "dls_ik",
    "make_whole_body_ik",
    "mujoco_frame_type",
    "pinv_ik",
    "solve_ik",
]
