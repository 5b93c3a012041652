"""Errors of the Unitree wire layer: the motor table, the message layout and the DDS channel."""

from __future__ import annotations

from mbctl.robots.exceptions import RobotError


class UnitreeError(RobotError):
    """Base class of the Unitree wire layer's errors."""


class MotorTableError(UnitreeError):
    """A robot whose joints do not match the motor table (a missing or an extra actuated joint)."""


class WireFormatError(UnitreeError):
    """A message of the wrong size or encoding (not the little-endian XCDR1 the robot sends)."""


class ChannelError(UnitreeError):
    """DDS cannot be set up: the extra is not installed, a bad domain id or network interface."""


class AnotherWriterError(ChannelError):
    """Another writer already publishes the topic this process would write on its DDS domain."""
