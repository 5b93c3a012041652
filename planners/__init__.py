"""Trajectory planners: ruckig (jerk-limited), polynomials, Cartesian paths."""

from mbctl.planners.exceptions import PlanningError
from mbctl.planners.trajectory import JointTrajectory

__all__ = ["JointTrajectory", "PlanningError"]
