"""Errors raised by the identification pipeline."""

from __future__ import annotations

from mbctl.robots.exceptions import RobotError


class IdentificationError(RobotError):
    """Base class of identification errors."""


class BadLogError(IdentificationError, ValueError):
    """A log identification cannot use: too short, not exciting, NaN, another robot's, columns missing.

    The message says which, with the values (rows, columns, rank) and what to do instead.
    """


class InconsistentParameters(IdentificationError):
    """Inertial parameters no physical body has (the message names the body and the failed test).

    Mass <= 0, an inertia that is not positive definite, a triangle inequality violated.
    """
