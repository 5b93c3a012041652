"""The one IK loop: iterate steps until every task is within tolerance, or the step vanishes.

Every iterative IK in the toolkit (the differential-IK QP :class:`~mbctl.control.ik.diff_ik.DiffIK`,
the whole-body backends, the 2-link pseudo-inverse and damped least squares) is an
:class:`IKStepper` run by :func:`iterate`, returns an :class:`IKResult`, and is judged by the one
convergence rule (:func:`mbctl.control.tasks.residuals.converged`).

An unreachable target is not an error: iteration stops when the step becomes negligible
(``stalled``) and the residuals say how far each task is from its target. The result keeps every
configuration visited (``q_path``), so a caller can check the whole path, not only its end (the
``mbctl ik`` job measures every step's collision distances in MuJoCo), and, for a solve with
priorities, each level's residual.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from typing import NamedTuple, Protocol

import numpy as np
import numpy.typing as npt

from mbctl.control.exceptions import IKSetupError
from mbctl.control.tasks.residuals import TaskResidual, Tolerance, converged, largest_position


class IKStepper(Protocol):
    """What :func:`iterate` drives: a configuration, its residuals and one step."""

    @property
    def q(self) -> np.ndarray:
        """Current configuration (nq,), Pinocchio convention (a copy)."""

    def update(self, q: npt.ArrayLike) -> None:
        """Move to configuration ``q`` (nq,)."""

    def task_residuals(self) -> dict[str, TaskResidual]:
        """Every task's residual at the current configuration, by task name."""

    @property
    def levels(self) -> tuple[tuple[str, ...], ...]:
        """Task names by priority level, level 0 first (one level: a weighted solve)."""

    def advance(self) -> float:
        """Take one step from the current configuration; return its size ``|dq|_inf`` [rad or m]."""


class IKResult(NamedTuple):
    """Outcome of iterating an IK to convergence.

    Attributes:
        q: Final configuration (nq,), Pinocchio convention.
        converged: Every non-regularising residual within its tolerance.
        stalled: Iteration stopped because the step became negligible before convergence (a local
            minimum: the target is out of reach, or the pose is singular for it).
        iterations: Steps taken.
        residuals: Each task's residual at ``q`` (units in the fields), by task name.
        position_history: The largest position residual [m] before each step and at the end
            (iterations + 1,).
        step_norms: Infinity norm of each tangent step (iterations,) [rad or m].
        iteration_times_s: Wall time of each step (iterations,) [s].
        wall_time_s: Wall time of the whole loop [s].
        q_path: Every configuration visited, ``q0`` first and ``q`` last (iterations + 1, nq).
        levels: Task names by priority level, level 0 first.
        level_residuals: Each level's residual at ``q``: the largest position [m] and orientation
            [rad] residual of its tasks (a level of regularisers only: their largest deviation).
    """

    q: np.ndarray
    converged: bool
    stalled: bool
    iterations: int
    residuals: dict[str, TaskResidual]
    position_history: np.ndarray
    step_norms: np.ndarray
    iteration_times_s: np.ndarray
    wall_time_s: float
    q_path: np.ndarray
    levels: tuple[tuple[str, ...], ...]
    level_residuals: tuple[TaskResidual, ...]


def iterate(stepper: IKStepper, q0: npt.ArrayLike, tolerance: Tolerance, max_iters: int = 50,
            step_tol: float = 1e-6) -> IKResult:
    """Step from ``q0`` (nq,) until every task meets ``tolerance``.

    Args:
        stepper: The IK (tasks, limits, solver).
        q0: Initial configuration (nq,), Pinocchio convention.
        tolerance: Position [m] and orientation [rad] tolerances.
        max_iters: Maximum number of steps (>= 1).
        step_tol: Stop when a step's inf-norm falls below this [rad or m] (0: never stall).

    Raises:
        IKSetupError: A negative step tolerance or fewer than one iteration.
        IKInfeasible: A step has no solution (QP backends).
    """
    if not (math.isfinite(step_tol) and step_tol >= 0.0) or int(max_iters) < 1:
        raise IKSetupError(f"step_tol must be >= 0 and max_iters >= 1; got step_tol={step_tol!r}, "
                           f"max_iters={max_iters!r}")
    t0 = time.perf_counter()
    stepper.update(q0)
    path = [stepper.q]
    history: list[float] = []
    steps: list[float] = []
    times: list[float] = []
    done = stalled = False
    for it in range(int(max_iters) + 1):
        residuals = stepper.task_residuals()
        done = converged(residuals, tolerance)
        history.append(largest_position(residuals))
        if done or stalled or it == int(max_iters):
            break
        t = time.perf_counter()
        steps.append(stepper.advance())
        times.append(time.perf_counter() - t)
        path.append(stepper.q)
        stalled = steps[-1] < step_tol
    levels = stepper.levels
    return IKResult(path[-1], done, stalled and not done, len(steps), residuals, np.array(history),
                    np.array(steps), np.array(times), time.perf_counter() - t0, np.array(path), levels,
                    tuple(largest_of([residuals[name] for name in level if name in residuals])
                          for level in levels))


def largest_of(residuals: Sequence[TaskResidual]) -> TaskResidual:
    """The largest position [m] and orientation [rad] among ``residuals`` (regularisers: deviation)."""
    positions = [r.position_m for r in residuals if r.position_m is not None]
    angles = [r.orientation_rad for r in residuals if r.orientation_rad is not None]
    if positions or angles:
        return TaskResidual(position_m=max(positions, default=None),
                            orientation_rad=max(angles, default=None))
    deviations = [r.deviation for r in residuals if r.deviation is not None]
    return TaskResidual(deviation=max(deviations, default=None))
