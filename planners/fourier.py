"""A periodic joint trajectory as a finite Fourier series (Swevers et al. 1997), starting at rest.

Per joint j, fundamental ``w = 2 pi / period_s``, harmonics l = 1..L::

    q_j(t) = c_j + sum_l  a_jl / (l w) sin(l w t) - b_jl / (l w) cos(l w t)
    v_j(t) =       sum_l  a_jl cos(l w t) + b_jl sin(l w t)
    a_j(t) =       sum_l -a_jl l w sin(l w t) + b_jl l w cos(l w t)

The series is periodic, so every period repeats the same motion (averaging over periods reduces
noise) and the motion stays bounded however long it runs. The coefficients are constrained so
the trajectory starts at rest at ``q_start``: ``sum_l a_jl = 0`` (v(0) = 0), ``sum_l l b_jl = 0``
(a(0) = 0), and ``c_j = q_start_j + sum_l b_jl / (l w)`` (q(0) = q_start).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from mbctl.planners._validation import check_names, check_time
from mbctl.planners.exceptions import InvalidPlanningInput
from mbctl.planners.trajectory import JointTrajectory


def rest_projection(harmonics: int) -> tuple[np.ndarray, np.ndarray]:
    """Projectors (L, L) onto the coefficients that start at rest: ``sum a = 0``, ``sum l b = 0``."""
    ones = np.ones(harmonics)
    ell = np.arange(1, harmonics + 1, dtype=float)
    P_a = np.eye(harmonics) - np.outer(ones, ones) / harmonics
    P_b = np.eye(harmonics) - np.outer(ell, ell) / (ell @ ell)
    return P_a, P_b


@dataclass(frozen=True)
class FourierTrajectory:
    """A Fourier-series joint trajectory that starts at rest (see the module docstring).

    Attributes:
        names: Joint names (n,).
        q_start: Start configuration (n,) [rad].
        period_s: Period of the fundamental [s].
        a: Cosine coefficients of v (n, L) [rad/s] (rows sum to zero).
        b: Sine coefficients of v (n, L) [rad/s] (``sum_l l b_jl = 0``).
    """

    names: tuple[str, ...]
    q_start: np.ndarray
    period_s: float
    a: np.ndarray
    b: np.ndarray

    def __post_init__(self) -> None:
        names = check_names(self.names)
        check_time("period_s", self.period_s)
        n = len(names)
        q0 = np.asarray(self.q_start, dtype=float).reshape(-1)
        a = np.asarray(self.a, dtype=float)
        b = np.asarray(self.b, dtype=float)
        if q0.shape != (n,) or a.ndim != 2 or a.shape[0] != n or b.shape != a.shape or a.shape[1] < 1:
            raise InvalidPlanningInput(f"q_start must be ({n},) and a, b ({n}, L) with L >= 1; got "
                                       f"{q0.shape}, {a.shape}, {b.shape}")
        if not (np.all(np.isfinite(q0)) and np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
            raise InvalidPlanningInput("q_start and the coefficients must be finite")
        ell = np.arange(1, a.shape[1] + 1)
        scale = max(float(np.abs(a).max()), float(np.abs(b).max()), 1e-12)
        if np.abs(a.sum(1)).max() > 1e-9 * scale or np.abs(b @ ell).max() > 1e-9 * scale:
            raise InvalidPlanningInput("the coefficients do not start at rest (sum_l a_jl and sum_l l b_jl "
                                       "must be 0); build them with FourierTrajectory.from_free")
        for name, arr in (("q_start", q0), ("a", a), ("b", b)):
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        object.__setattr__(self, "names", names)

    @classmethod
    def from_free(cls, names: tuple[str, ...], q_start: npt.ArrayLike, period_s: float,
                  a_free: npt.ArrayLike, b_free: npt.ArrayLike) -> FourierTrajectory:
        """The trajectory whose coefficients are ``a_free``, ``b_free`` (n, L) projected to start at rest."""
        a_free = np.asarray(a_free, dtype=float)
        P_a, P_b = rest_projection(a_free.shape[1])
        return cls(tuple(names), np.asarray(q_start, dtype=float), float(period_s), a_free @ P_a,
                   np.asarray(b_free, dtype=float) @ P_b)

    @property
    def harmonics(self) -> int:
        """Number of harmonics L."""
        return int(self.a.shape[1])

    @property
    def omega_rad_s(self) -> float:
        """Fundamental angular frequency [rad/s]."""
        return 2.0 * np.pi / self.period_s

    @property
    def max_frequency_hz(self) -> float:
        """Highest frequency in the trajectory [Hz]."""
        return self.harmonics / self.period_s

    def sample(self, t_s: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """q, v, a at times ``t_s`` (N,) [s]: arrays (N, n) [rad, rad/s, rad/s^2]."""
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        w = self.omega_rad_s
        lw = w * np.arange(1, self.harmonics + 1)            # (L,)
        s, c = np.sin(np.outer(t, lw)), np.cos(np.outer(t, lw))  # (N, L)
        offset = self.q_start + (self.b / lw).sum(1)
        q = offset + s @ (self.a / lw).T - c @ (self.b / lw).T
        v = c @ self.a.T + s @ self.b.T
        acc = -s @ (self.a * lw).T + c @ (self.b * lw).T
        return q, v, acc

    def trajectory(self, dt_s: float, duration_s: float) -> JointTrajectory:
        """The trajectory sampled every ``dt_s`` [s] over ``duration_s`` [s]."""
        check_time("dt_s", dt_s)
        check_time("duration_s", duration_s)
        t = np.arange(int(round(duration_s / dt_s)) + 1) * dt_s
        q, v, a = self.sample(t)
        return JointTrajectory(t, q, v, a, self.names)
