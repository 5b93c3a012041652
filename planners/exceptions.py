"""Errors raised by trajectory planners."""

from __future__ import annotations

from typing import Any

from mbctl.exceptions import ToolkitError


class PlanningError(ToolkitError):
    """Base class of planner errors."""


class InvalidLimits(PlanningError, ValueError):
    """A kinematic limit that is not positive and finite, or has the wrong number of DoFs.

    The message names the quantity, the DoF index, the value and the bound.
    """


class InvalidPlanningInput(PlanningError, ValueError):
    """A planner input (state, duration, control period, names, waypoints) that is invalid.

    The message names the argument, its value or shape, and what is allowed.
    """


class TrajectoryGenerationFailed(PlanningError):
    """Ruckig rejected the input or could not compute a trajectory.

    Attributes:
        result: The ruckig ``Result`` name (e.g. ``"ErrorInvalidInput"``), or ``"RuckigError"``
            when the bindings raised instead of returning an error code.
        details: Ruckig's own explanation (its exception text), possibly empty.
    """

    def __init__(self, message: str, result: str, details: str = ""):
        self.result = result
        self.details = details
        super().__init__(message)


class InvalidPath(PlanningError, ValueError):
    """A Cartesian path with degenerate geometry or a path that a conversion cannot follow.

    Examples: zero length or radius, a normal parallel to the start direction, repeated
    vertices, or motion along an axis the Jacobian does not cover.
    """


class PathIKFailed(PlanningError):
    """The inverse kinematics raised at a sample of a Cartesian trajectory.

    The original exception is chained as ``__cause__`` and kept in ``cause``.

    Attributes:
        t_s: Time of the failing sample [s].
        sample_index: Index of the failing sample.
        position: The Cartesian target passed to the IK [m].
        cause: The exception the IK raised.
    """

    def __init__(self, t_s: float, sample_index: int, position: Any, cause: BaseException):
        self.t_s = t_s
        self.sample_index = sample_index
        self.position = position
        self.cause = cause
        super().__init__(
            f"IK failed at t = {t_s:.6g} s (sample {sample_index}) for the Cartesian target "
            f"{[float(x) for x in position]} m: {type(cause).__name__}: {cause}. Move or shrink "
            "the path so that every point is reachable."
        )


class PathNotTrackable(PlanningError):
    """The joint velocity or acceleration cannot reproduce the Cartesian one at a sample.

    This happens at (or numerically near) a singular Jacobian, where the pseudo-inverse drops
    the component of the Cartesian velocity that the arm cannot produce.

    Attributes:
        t_s: Time of the sample [s].
        sample_index: Index of the sample.
        residual: ``|J qd - v|`` [m/s] or ``|J qdd + Jdot qd - a|`` [m/s^2] at that sample.
    """

    def __init__(self, message: str, t_s: float, sample_index: int, residual: float):
        self.t_s = t_s
        self.sample_index = sample_index
        self.residual = residual
        super().__init__(message)
