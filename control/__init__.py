"""mbctl.control: controllers, kinematics and inverse kinematics (never imports mbctl.sim)."""

from mbctl.control.exceptions import (
    ControlError,
    IKInfeasible,
    IKSetupError,
    KinematicsError,
    UnreachableTarget,
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
    "ControlError",
    "ElbowBranch",
    "IKInfeasible",
    "IKSetupError",
    "IterativeIKResult",
    "KinematicsError",
    "TwoLinkArm",
    "UnreachableTarget",
    "Workspace",
    "dls_ik",
    "pinv_ik",
    "plot_workspace",
]
