"""Errors raised by trajectory planners."""

from mbctl.exceptions import ToolkitError


class PlanningError(ToolkitError):
    """Base class of planner errors."""
