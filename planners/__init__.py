"""Trajectory planners: ruckig (jerk-limited), polynomials, Cartesian paths and their timing."""

from mbctl.planners.cartesian import (
    CartesianTrajectory,
    PathLimits,
    time_path,
    to_joint_trajectory,
)
from mbctl.planners.exceptions import (
    InvalidLimits,
    InvalidPath,
    InvalidPlanningInput,
    PathIKFailed,
    PathNotTrackable,
    PlanningError,
    TrajectoryGenerationFailed,
)
from mbctl.planners.paths import CartesianPath, CirclePath, LinePath, PolylinePath, square_path
from mbctl.planners.polynomial import (
    cubic_trajectory,
    minimum_jerk_at,
    minimum_jerk_trajectory,
    quintic_trajectory,
)
from mbctl.planners.ruckig_planner import (
    JointLimits,
    concatenate,
    pass_through_velocities,
    plan_ruckig,
    plan_waypoints,
)
from mbctl.planners.trajectory import JointTrajectory

__all__ = [
    "CartesianPath",
    "CartesianTrajectory",
    "CirclePath",
    "InvalidLimits",
    "InvalidPath",
    "InvalidPlanningInput",
    "JointLimits",
    "JointTrajectory",
    "LinePath",
    "PathIKFailed",
    "PathLimits",
    "PathNotTrackable",
    "PlanningError",
    "PolylinePath",
    "TrajectoryGenerationFailed",
    "concatenate",
    "cubic_trajectory",
    "minimum_jerk_at",
    "minimum_jerk_trajectory",
    "pass_through_velocities",
    "plan_ruckig",
    "plan_waypoints",
    "quintic_trajectory",
    "square_path",
    "time_path",
    "to_joint_trajectory",
]
