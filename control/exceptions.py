"""Errors raised by controllers, tasks, inverse kinematics and whole-body control."""

from __future__ import annotations

from typing import Any

from mbctl.exceptions import ToolkitError


class ControlError(ToolkitError):
    """Base class of control-side errors."""


class KinematicsError(ControlError):
    """A model whose geometry does not fit an analytic kinematics module (e.g. not planar)."""


class UnreachableTarget(ControlError, ValueError):
    """An analytic IK target outside the reachable workspace.

    Attributes:
        target: The requested position [m] (world frame).
        radius: Its distance from the base [m].
        r_min: Inner radius of the reachable annulus [m].
        r_max: Outer radius of the reachable annulus [m].
    """

    def __init__(self, target: Any, radius: float, r_min: float, r_max: float):
        self.target = target
        self.radius = radius
        self.r_min = r_min
        self.r_max = r_max
        super().__init__(
            f"Target {list(map(float, target))} m is at radius {radius:.6g} m from the base, "
            f"outside the reachable annulus r_min={r_min:.6g} m .. r_max={r_max:.6g} m. "
            "Move the target into the annulus, or use an iterative IK (it returns the closest "
            "pose)."
        )


class TaskSetupError(ControlError, ValueError):
    """A task (weights, gains, target, frame) or task state with an invalid value (named in the message)."""


class IKSetupError(ControlError, ValueError):
    """An IK task, limit or solver option with an invalid value (named in the message)."""


class IKInfeasible(ControlError):
    """The differential-IK QP has no solution (e.g. contradictory limits).

    Attributes:
        problem: The ``qpsolvers.Problem`` that failed, for inspection or re-solving.
        result: The solver's ``qpsolvers.Solution`` (``found`` is False).
        solver: Name of the QP backend.
    """

    def __init__(self, message: str, problem: Any, result: Any, solver: str):
        self.problem = problem
        self.result = result
        self.solver = solver
        super().__init__(message)


class GainsError(ControlError, ValueError):
    """Controller gains with a wrong shape, a non-finite or a negative value (named in the message)."""


class ControllerSetupError(ControlError, ValueError):
    """A controller that cannot be built for this robot (joints, actuators, model sizes)."""


class ReferenceMismatch(ControlError, ValueError):
    """A reference whose shape or names do not match the controller's joints or task."""


class SingularJacobian(ControlError):
    """A task Jacobian that cannot be inverted at the current configuration (a singularity).

    Attributes:
        q: The configuration (nq,) [rad] where it happened.
    """

    def __init__(self, message: str, q: Any):
        self.q = q
        super().__init__(message)


class WBCSetupError(ControlError, ValueError):
    """A whole-body controller option, task or contact with an invalid value (named in the message)."""


class WBCInfeasible(ControlError):
    """The whole-body inverse-dynamics QP has no solution (e.g. torque limits below gravity load).

    Attributes:
        problem: The ``qpsolvers.Problem`` that failed, for inspection or re-solving.
        result: The solver's ``qpsolvers.Solution`` (``found`` is False).
        solver: Name of the QP backend.
        time_s: The state's time [s] when it failed, if known.
    """

    def __init__(self, message: str, problem: Any, result: Any, solver: str, time_s: float | None = None):
        self.problem = problem
        self.result = result
        self.solver = solver
        self.time_s = time_s
        super().__init__(message)
