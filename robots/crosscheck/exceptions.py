"""Errors of the Pinocchio-vs-MuJoCo cross-check."""

from __future__ import annotations

from mbctl.robots.exceptions import RobotError


class CrossCheckError(RobotError):
    """Invalid cross-check arguments (number of states, seed, tolerances, progress hook)."""
