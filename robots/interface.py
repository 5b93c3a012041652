"""The robot API controllers are written against: read state, send a command, keep time.

It lives in robots/ (not sim/) because control/ never imports sim/. The simulator implements
it; a hardware driver would implement the same protocol.
"""

from __future__ import annotations

from typing import NamedTuple, Protocol, runtime_checkable

import numpy as np

from mbctl.robots.commands import Command
from mbctl.robots.model_pair import Robot


class RobotState(NamedTuple):
    """Measured state in Pinocchio's convention.

    Attributes:
        q: Configuration (nq,); free-flyer quaternion (x, y, z, w). Read-only copy.
        v: Velocity (nv,); free-flyer linear velocity in the base frame. Read-only copy.
        time_s: Time of the measurement [s].
    """

    q: np.ndarray
    v: np.ndarray
    time_s: float


@runtime_checkable
class RobotInterface(Protocol):
    """A robot that can be read and commanded at a fixed control period."""

    @property
    def robot(self) -> Robot:
        """The robot's model pair."""

    @property
    def control_period_s(self) -> float:
        """Duration [s] of one control cycle (``sync`` advances by this much)."""

    @property
    def time_s(self) -> float:
        """Current time [s]."""

    def read_state(self) -> RobotState:
        """The latest measured state."""

    def send(self, command: Command) -> None:
        """Apply a command; it holds until the next one."""

    def sync(self) -> None:
        """Wait for the next control cycle (a simulator steps the physics for one period)."""
