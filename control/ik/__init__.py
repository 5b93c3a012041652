"""Differential inverse kinematics: the QP, limits, the one IK loop, whole-body backends, chain and 2-link IK.

The tasks themselves live in :mod:`mbctl.control.tasks` (shared with whole-body inverse dynamics).
"""

from mbctl.control.ik.chain import ChainIK, chain_joints
from mbctl.control.ik.collision import CollisionAvoidanceLimit
from mbctl.control.ik.config import WholeBodyIKConfig
from mbctl.control.ik.diff_ik import DiffIK, IKStep, solve_ik
from mbctl.control.ik.factory import BACKENDS, make_whole_body_ik
from mbctl.control.ik.limits import (
    BoxLimit,
    Constraint,
    FloatingBaseVelocityLimit,
    JointPositionLimit,
    JointVelocityLimit,
    Limit,
)
from mbctl.control.ik.loop import IKResult, IKStepper, iterate
from mbctl.control.ik.mink_backend import MinkWholeBodyIK
from mbctl.control.ik.two_link import ElbowBranch, TwoLinkArm, Workspace, dls_ik, pinv_ik
from mbctl.control.ik.whole_body import (
    FrameTarget,
    QPWholeBodyIK,
    WholeBodyIK,
    joint_positions_by_name,
    mujoco_frame_type,
)

__all__ = [
    "BACKENDS",
    "BoxLimit",
    "ChainIK",
    "CollisionAvoidanceLimit",
    "Constraint",
    "DiffIK",
    "ElbowBranch",
    "FloatingBaseVelocityLimit",
    "FrameTarget",
    "IKResult",
    "IKStep",
    "IKStepper",
    "JointPositionLimit",
    "JointVelocityLimit",
    "Limit",
    "MinkWholeBodyIK",
    "QPWholeBodyIK",
    "TwoLinkArm",
    "WholeBodyIK",
    "WholeBodyIKConfig",
    "Workspace",
    "chain_joints",
    "dls_ik",
    "iterate",
    "joint_positions_by_name",
    "make_whole_body_ik",
    "mujoco_frame_type",
    "pinv_ik",
    "solve_ik",
]
