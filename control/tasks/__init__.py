"""The task layer: task states, one module per task type, residuals, and the stacked objective.

Differential IK (:mod:`mbctl.control.ik`) and whole-body inverse dynamics
(:mod:`mbctl.control.wbc`) are peers above it: both take these tasks, one at the velocity level
and one at the acceleration level (:mod:`mbctl.control.tasks.base` states the math).
"""

from mbctl.control.tasks.angular_momentum import AngularMomentumTask
from mbctl.control.tasks.base import AccelerationGains, Task
from mbctl.control.tasks.com import ComTask
from mbctl.control.tasks.damping import DampingTask
from mbctl.control.tasks.diagonal import DiagonalTask
from mbctl.control.tasks.frame import FrameTask
from mbctl.control.tasks.frame_orientation import FrameOrientationTask
from mbctl.control.tasks.frame_pose import FramePoseTask
from mbctl.control.tasks.frame_position import FramePositionTask
from mbctl.control.tasks.posture import PostureTask
from mbctl.control.tasks.relative_frame import RelativeFrameTask
from mbctl.control.tasks.residuals import TaskResidual, Tolerance, converged, residual_table
from mbctl.control.tasks.stack import TaskStack
from mbctl.control.tasks.state import DynamicsState, KinematicState, TaskState

__all__ = [
    "AccelerationGains",
    "AngularMomentumTask",
    "ComTask",
    "DampingTask",
    "DiagonalTask",
    "DynamicsState",
    "FrameOrientationTask",
    "FramePoseTask",
    "FramePositionTask",
    "FrameTask",
    "KinematicState",
    "PostureTask",
    "RelativeFrameTask",
    "Task",
    "TaskResidual",
    "TaskStack",
    "TaskState",
    "Tolerance",
    "converged",
    "residual_table",
]
