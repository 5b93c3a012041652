"""Planners: ruckig (jerk-limited), polynomials, Cartesian paths and their timing; walking.

Walking: footsteps from a velocity command or waypoints (:mod:`mbctl.planners.footsteps`), the DCM
plan and its feedback law (:mod:`mbctl.planners.dcm`), the swing foot (:mod:`mbctl.planners.swing`).
"""

from mbctl.planners.cartesian import (
    CartesianTrajectory,
    PathLimits,
    time_path,
    to_joint_trajectory,
)
from mbctl.planners.dcm import (
    ConvexPolygon,
    DcmPlan,
    DcmReference,
    clamp_to_polygon,
    convex_hull,
    dcm_feedback,
    dcm_omega,
    polygon_margin,
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
from mbctl.planners.footsteps import (
    CommandClamp,
    Footstep,
    FootstepPlanner,
    GaitTiming,
    StepLimits,
    VelocityCommand,
    WaypointFollower,
    step_limits_from_model,
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
from mbctl.planners.swing import SwingSample, SwingTrajectory, polynomial_at, quintic_coefficients
from mbctl.planners.trajectory import JointTrajectory

__all__ = [
    "CartesianPath",
    "CartesianTrajectory",
    "CirclePath",
    "CommandClamp",
    "ConvexPolygon",
    "DcmPlan",
    "DcmReference",
    "Footstep",
    "FootstepPlanner",
    "GaitTiming",
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
    "StepLimits",
    "SwingSample",
    "SwingTrajectory",
    "TrajectoryGenerationFailed",
    "VelocityCommand",
    "WaypointFollower",
    "clamp_to_polygon",
    "concatenate",
    "convex_hull",
    "cubic_trajectory",
    "dcm_feedback",
    "dcm_omega",
    "minimum_jerk_at",
    "minimum_jerk_trajectory",
    "pass_through_velocities",
    "plan_ruckig",
    "plan_waypoints",
    "polygon_margin",
    "polynomial_at",
    "quintic_coefficients",
    "quintic_trajectory",
    "square_path",
    "step_limits_from_model",
    "time_path",
    "to_joint_trajectory",
]
