"""Errors of the hardware interfaces, each saying what happened and what to check."""

from __future__ import annotations

from mbctl.exceptions import ToolkitError


class HardwareError(ToolkitError):
    """Base class of the hardware interfaces' errors."""


class NoRobotError(HardwareError):
    """No valid state from the robot within the connect timeout (nothing was commanded)."""


class JointOutOfLimits(HardwareError):
    """A joint outside its limits when the interface starts (nothing was commanded)."""


class LinkLost(HardwareError):
    """The robot's state stopped arriving during the run; the damping command was sent."""


class DryRunError(HardwareError):
    """A command sent to an interface opened with ``dry_run``: it never commands."""
