"""Task residuals with their units in their types, and the one convergence rule.

A task's residual is a :class:`TaskResidual`: a distance in metres, an angle in radians, or a
joint-space deviation (the posture regulariser's, which never gates convergence). Tolerances are a
:class:`Tolerance` with the same units, and :func:`converged` is the only rule that compares the
two, so IK loops, jobs and tests cannot disagree on what "converged" means (or decide units from
a string).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import NamedTuple

from mbctl.control.exceptions import TaskSetupError


class TaskResidual(NamedTuple):
    """How far one task is from its target.

    Attributes:
        position_m: Distance to the target position [m] (None: the task has no position part).
        orientation_rad: Rotation angle to the target orientation [rad] (None: no orientation part).
        deviation: Joint-space distance of a regulariser (posture) [rad, or m for slide joints];
            reported, never compared with a tolerance.
    """

    position_m: float | None = None
    orientation_rad: float | None = None
    deviation: float | None = None

    @property
    def regularising(self) -> bool:
        """True for a regulariser's residual (no position or orientation part): it never gates."""
        return self.position_m is None and self.orientation_rad is None

    def as_dict(self) -> dict[str, float]:
        """The parts that are set, keyed with their unit (``"position [m]"``), for reports."""
        out = {}
        if self.position_m is not None:
            out["position [m]"] = self.position_m
        if self.orientation_rad is not None:
            out["orientation [rad]"] = self.orientation_rad
        if self.deviation is not None:
            out["deviation [rad]"] = self.deviation
        return out


@dataclass(frozen=True)
class Tolerance:
    """Convergence tolerances.

    Attributes:
        position_m: Largest accepted position residual [m] (> 0).
        orientation_rad: Largest accepted orientation residual [rad] (> 0).
    """

    position_m: float = 1e-3
    orientation_rad: float = 1e-2

    def __post_init__(self) -> None:
        for name in ("position_m", "orientation_rad"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise TaskSetupError(f"Tolerance.{name} must be > 0; got {value!r}")

    def accepts(self, residual: TaskResidual) -> bool:
        """Whether every gating part of ``residual`` is within its tolerance."""
        if residual.position_m is not None and not residual.position_m <= self.position_m:
            return False
        return residual.orientation_rad is None or residual.orientation_rad <= self.orientation_rad


def converged(residuals: Mapping[str, TaskResidual], tolerance: Tolerance) -> bool:
    """Every task's residual within ``tolerance`` (regularisers excepted): the one convergence rule."""
    return all(tolerance.accepts(r) for r in residuals.values())


def largest_position(residuals: Mapping[str, TaskResidual]) -> float:
    """The largest position residual [m] among the tasks (0.0 when no task has one)."""
    return max((r.position_m for r in residuals.values() if r.position_m is not None), default=0.0)


def residual_table(residuals: Mapping[str, TaskResidual]) -> dict[str, dict[str, float]]:
    """``{task: {"position [m]": ..., ...}}`` for JSON reports and printing."""
    return {name: r.as_dict() for name, r in residuals.items()}
