"""Errors raised by controllers and inverse kinematics."""

from mbctl.exceptions import ToolkitError


class ControlError(ToolkitError):
    """Base class of control-side errors."""
