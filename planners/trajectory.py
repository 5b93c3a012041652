"""A sampled joint-space trajectory: the one type every planner returns and controllers consume."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mbctl.planners.exceptions import PlanningError


class _UniformGrid:
    """Timing of samples on a uniform grid ``t_s`` (N,) [s] that starts at 0."""

    t_s: np.ndarray

    @property
    def duration_s(self) -> float:
        """Time of the last sample [s]."""
        return float(self.t_s[-1])

    @property
    def dt_s(self) -> float:
        """Sample period [s] (0 for a single sample)."""
        return float(self.t_s[1] - self.t_s[0]) if len(self.t_s) > 1 else 0.0


@dataclass(frozen=True)
class JointTrajectory(_UniformGrid):
    """Positions, velocities and accelerations sampled on a uniform time grid.

    Attributes:
        t_s: Sample times (N,) [s], uniform step ``dt_s``, starting at 0.
        q: Positions (N, n) [rad] or [m].
        v: Velocities (N, n) [rad/s].
        a: Accelerations (N, n) [rad/s^2].
        names: Joint names of the n columns.
    """

    t_s: np.ndarray
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    names: tuple[str, ...]

    def __post_init__(self) -> None:
        n_samples = len(self.t_s)
        for field_name in ("q", "v", "a"):
            arr = np.asarray(getattr(self, field_name), dtype=float)
            if arr.ndim != 2 or arr.shape != (n_samples, len(self.names)):
                raise PlanningError(
                    f"JointTrajectory.{field_name} must have shape "
                    f"({n_samples}, {len(self.names)}); got {arr.shape}"
                )
            if not np.all(np.isfinite(arr)):
                raise PlanningError(f"JointTrajectory.{field_name} has non-finite samples")
            arr.setflags(write=False)
            object.__setattr__(self, field_name, arr)
        t = np.asarray(self.t_s, dtype=float)
        if n_samples < 1 or (n_samples > 1 and not np.all(np.diff(t) > 0)):
            raise PlanningError("JointTrajectory.t_s must be non-empty and strictly increasing")
        t.setflags(write=False)
        object.__setattr__(self, "t_s", t)

    def sample(self, t_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q, v, a) at time ``t_s`` [s].

        Linear interpolation inside; outside, the end state is held (zero velocity and
        acceleration after the end).
        """
        if t_s >= self.t_s[-1]:
            return self.q[-1].copy(), np.zeros(len(self.names)), np.zeros(len(self.names))
        if t_s <= self.t_s[0]:
            return self.q[0].copy(), self.v[0].copy(), self.a[0].copy()
        i = int(np.searchsorted(self.t_s, t_s, side="right")) - 1
        w = (t_s - self.t_s[i]) / (self.t_s[i + 1] - self.t_s[i])
        return (
            (1 - w) * self.q[i] + w * self.q[i + 1],
            (1 - w) * self.v[i] + w * self.v[i + 1],
            (1 - w) * self.a[i] + w * self.a[i + 1],
        )

    def then(self, other: JointTrajectory) -> JointTrajectory:
        """This trajectory followed by ``other``.

        Same names and dt; ``other`` starts where this one ends.
        """
        if other.names != self.names:
            raise PlanningError(f"cannot chain trajectories over {self.names} and {other.names}")
        shift = self.t_s[-1] + (other.t_s[0] if other.t_s[0] > 0 else self.dt_s or other.dt_s)
        keep = slice(1, None) if np.allclose(other.q[0], self.q[-1]) else slice(None)
        return JointTrajectory(
            np.concatenate([self.t_s, other.t_s[keep] - other.t_s[keep][0] + shift])
            if len(other.t_s[keep]) else self.t_s,
            np.vstack([self.q, other.q[keep]]),
            np.vstack([self.v, other.v[keep]]),
            np.vstack([self.a, other.a[keep]]),
            self.names,
        )

