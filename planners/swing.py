"""The swing foot: a lift and a smooth path from lift-off to touchdown, at rest at both ends.

The path is planned in W over the single-support time T, from the foot's pose at lift-off to its
footstep; each coordinate is a quintic polynomial (position, velocity and acceleration given at
both ends, the closed form of ``mbctl.planners.polynomial`` evaluated at one time, for the
control cycle):

- **Horizontal** (x, y) and **yaw**: from the lift-off state to the footstep at rest, over the
  first ``horizontal_fraction`` of T (the rest of the swing is a vertical descent, so the foot
  lands without sliding even when it touches down early). The footstep may move during the swing
  (a new velocity command, a re-planned step): :meth:`SwingTrajectory.retarget`
  starts a new quintic from the current position, velocity and acceleration to the new footstep
  over the horizontal time left, so the path stays twice differentiable; once less than
  ``MIN_RETARGET_S`` of it is left, the footstep is frozen (a late change would need an
  acceleration the leg cannot give).
- **Timing**: the touchdown may come sooner (step timing adaptation): :meth:`SwingTrajectory.retime`
  re-plans the horizontal motion and the height from the path's state to the same footstep over the
  new swing, so a quicker swing still lands on its footstep, at rest, at its new end.
- **Height**: up from the lift-off height ``z0`` to ``max(z0, z1) + h`` at ``T/2`` and down to the
  footstep's height ``z1`` at T, each half a quintic at rest at its ends, so the foot leaves and
  lands with zero velocity and zero acceleration and passes the apex with zero vertical velocity.

After T the sample holds the footstep at rest (a late touchdown is the controller's business:
it lowers the foot further, see :mod:`mbctl.control.wbc.walking`).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from mbctl.planners._validation import check_time
from mbctl.planners.exceptions import InvalidPlanningInput

#: A footstep change with less swing time left than this [s] is ignored (the path is frozen).
MIN_RETARGET_S = 0.05


def quintic_coefficients(p0: npt.ArrayLike, v0: npt.ArrayLike, a0: npt.ArrayLike, p1: npt.ArrayLike,
                         v1: npt.ArrayLike, a1: npt.ArrayLike, duration_s: float) -> np.ndarray:
    """Coefficients (6, n) of ``p(t) = sum_k c_k t^k`` matching (p, v, a) at t = 0 and t = T.

    The closed form of :func:`mbctl.planners.polynomial.quintic_trajectory`, for evaluation at
    single times (:func:`polynomial_at`).

    Args:
        p0: Start position (n,) (scalars broadcast, as for every end value).
        v0: Start velocity (n,) [unit/s].
        a0: Start acceleration (n,) [unit/s^2].
        p1: End position (n,).
        v1: End velocity (n,) [unit/s].
        a1: End acceleration (n,) [unit/s^2].
        duration_s: T [s] (> 0).

    Raises:
        InvalidPlanningInput: A non-positive or non-finite duration, or end values of other shapes.
    """
    return np.array(list(zip(*quintic_columns(p0, v0, a0, p1, v1, a1, duration_s), strict=True)))


def quintic_columns(p0: npt.ArrayLike, v0: npt.ArrayLike, a0: npt.ArrayLike, p1: npt.ArrayLike,
                    v1: npt.ArrayLike, a1: npt.ArrayLike, duration_s: float) -> list[tuple[float, ...]]:
    """:func:`quintic_coefficients` as plain floats, by coordinate: n tuples ``(c_0, ..., c_5)``.

    For :func:`quintic_columns_at` (a path sampled every control cycle, where numpy's per-call cost
    would be most of the work).

    Raises:
        InvalidPlanningInput: A non-positive or non-finite duration, or end values of other shapes.
    """
    T = check_time("duration_s", duration_s)
    values = [_floats(x) for x in (p0, v0, a0, p1, v1, a1)]
    ends = [e for e in values if e is not None]
    n = max((len(e) for e in ends), default=0)
    if len(ends) < 6 or any(len(e) not in (1, n) for e in ends):
        shapes = [np.shape(x) for x in (p0, v0, a0, p1, v1, a1)]
        raise InvalidPlanningInput(f"the end values must be scalars or vectors of one length (n,); got "
                                   f"shapes {shapes}")
    T2, T3, T4, T5 = T**2, 2.0 * T**3, 2.0 * T**4, 2.0 * T**5
    columns: list[tuple[float, ...]] = []
    for i in range(n):
        p, v, a, q, w, b = (e[0] if len(e) == 1 else e[i] for e in ends)
        dq = q - p
        columns.append((p, v, 0.5 * a,
                        (20.0 * dq - (8.0 * w + 12.0 * v) * T - (3.0 * a - b) * T2) / T3,
                        (-30.0 * dq + (14.0 * w + 16.0 * v) * T + (3.0 * a - 2.0 * b) * T2) / T4,
                        (12.0 * dq - 6.0 * (w + v) * T - (a - b) * T2) / T5))
    return columns


def quintic_columns_at(columns: list[tuple[float, ...]], t_s: float
                       ) -> tuple[list[float], list[float], list[float]]:
    """Position, velocity and acceleration (n floats each) of :func:`quintic_columns`' polynomials at t_s."""
    t = t_s
    t2 = t * t
    t3 = t2 * t
    t4 = t3 * t
    t5 = t4 * t
    p, v, a = [], [], []
    for c0, c1, c2, c3, c4, c5 in columns:
        p.append(c0 + c1 * t + c2 * t2 + c3 * t3 + c4 * t4 + c5 * t5)
        v.append(c1 + 2.0 * c2 * t + 3.0 * c3 * t2 + 4.0 * c4 * t3 + 5.0 * c5 * t4)
        a.append(2.0 * c2 + 6.0 * c3 * t + 12.0 * c4 * t2 + 20.0 * c5 * t3)
    return p, v, a


def _floats(x: npt.ArrayLike) -> list[float] | None:
    """A scalar's or a vector's values as floats (None for anything else)."""
    if isinstance(x, float):
        return [x]
    if type(x) is list and all(type(v) is float for v in x):
        return x
    if type(x) is np.ndarray and x.ndim == 1 and x.dtype == np.float64:
        return x.tolist()
    a = np.asarray(x, dtype=float)
    return a.ravel().tolist() if a.ndim <= 1 else None


def polynomial_at(coeffs: np.ndarray, t_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position, velocity and acceleration of ``sum_k coeffs[k] t^k`` at ``t_s`` (coeffs (K, n))."""
    t = float(t_s)
    powers = [t**k for k in range(len(coeffs))]
    p = np.dot(powers, coeffs)
    v = np.dot([k * powers[k - 1] for k in range(1, len(coeffs))], coeffs[1:])
    a = np.dot([k * (k - 1) * powers[k - 2] for k in range(2, len(coeffs))], coeffs[2:])
    return p, v, a


class SwingSample(NamedTuple):
    """The swing foot's reference at one time, in W.

    Attributes:
        position: Foot frame origin (3,) [m].
        velocity: Its velocity (3,) [m/s].
        acceleration: Its acceleration (3,) [m/s^2].
        yaw_rad: Foot yaw [rad] (the foot stays level: roll and pitch 0).
        yaw_rate_rad_s: Yaw rate [rad/s].
        phase: Fraction of the swing time elapsed, in [0, 1].
        yaw_acceleration_rad_s2: Yaw acceleration [rad/s^2].
    """

    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    yaw_rad: float
    yaw_rate_rad_s: float
    phase: float
    yaw_acceleration_rad_s2: float = 0.0


class SwingTrajectory:
    """The swing foot's path from lift-off at ``t0_s`` to its footstep at ``t0_s + duration_s``.

    Args:
        start_position: Foot frame origin at lift-off (3,) [m] in W.
        start_yaw_rad: Foot yaw at lift-off [rad].
        target_position: The footstep's foot frame origin (3,) [m] in W.
        target_yaw_rad: The footstep's yaw [rad] (taken within pi of the start: the short way).
        duration_s: Single-support time T [s] (> 0).
        lift_height_m: Apex height [m] above the higher of the two ends (>= 0).
        t0_s: Lift-off time [s].
        horizontal_fraction: The horizontal motion and the yaw end at this fraction of T (in (0, 1]).

    Raises:
        InvalidPlanningInput: Non-finite poses, a non-positive duration, a negative lift or a
            horizontal fraction outside (0, 1].
    """

    def __init__(self, start_position: npt.ArrayLike, start_yaw_rad: float, target_position: npt.ArrayLike,
                 target_yaw_rad: float, duration_s: float, lift_height_m: float, t0_s: float = 0.0,
                 horizontal_fraction: float = 1.0):
        self.duration_s = check_time("duration_s", duration_s)
        if not (math.isfinite(lift_height_m) and lift_height_m >= 0.0):
            raise InvalidPlanningInput(f"lift_height_m must be finite and >= 0 [m]; got {lift_height_m!r}")
        if not (math.isfinite(horizontal_fraction) and 0.0 < horizontal_fraction <= 1.0):
            raise InvalidPlanningInput(f"horizontal_fraction must be in (0, 1]; got {horizontal_fraction!r}")
        self.horizontal_fraction = float(horizontal_fraction)
        self.horizontal_end_s = float(t0_s) + horizontal_fraction * self.duration_s
        p0 = _point("start_position", start_position)
        p1 = _point("target_position", target_position)
        self.t0_s = float(t0_s)
        self.lift_height_m = float(lift_height_m)
        start = np.array([p0[0], p0[1], float(start_yaw_rad)])
        if not np.all(np.isfinite(start)):
            raise InvalidPlanningInput(f"start_yaw_rad must be finite; got {start_yaw_rad!r}")
        self._plane_t0 = self.t0_s
        # the path's polynomials by coordinate, on plain floats (sampled every control cycle)
        self._plane = quintic_columns(start, 0.0, 0.0, self._goal(float(start[2]), p1, target_yaw_rad),
                                      0.0, 0.0, self.horizontal_end_s - self.t0_s)
        self.target_position = p1
        self.target_yaw_rad = float(self._plane_end()[2])
        half = 0.5 * self.duration_s
        apex = max(p0[2], p1[2]) + self.lift_height_m
        self._cache: tuple[float, tuple] | None = None  # the last sample's floats (a cycle asks for it again)
        self._plane_end_cache: list[float] | None = None  # x, y, yaw at the horizontal motion's end
        self._plane_cache: tuple[float, tuple[list[float], list[float], list[float]]] | None = None
        self._apex_m = float(apex)
        #: The height's pieces (start [s] after lift-off, columns): each a quintic from its start on.
        z0, z1 = float(p0[2]), float(p1[2])
        self._height = [(0.0, quintic_columns(z0, 0.0, 0.0, self._apex_m, 0.0, 0.0, half)),
                        (half, quintic_columns(self._apex_m, 0.0, 0.0, z1, 0.0, 0.0, half))]

    @property
    def end_s(self) -> float:
        """Planned touchdown time [s]."""
        return self.t0_s + self.duration_s

    def _plane_end(self) -> list[float]:
        return quintic_columns_at(self._plane, self.horizontal_end_s - self._plane_t0)[0]

    @staticmethod
    def _goal(yaw_now: float, target: np.ndarray, target_yaw_rad: float) -> list[float]:
        if not math.isfinite(target_yaw_rad):
            raise InvalidPlanningInput(f"target_yaw_rad must be finite; got {target_yaw_rad!r}")
        yaw = yaw_now + math.remainder(float(target_yaw_rad) - yaw_now, 2.0 * math.pi)
        x, y, _ = target.tolist()
        return [x, y, yaw]

    def retarget(self, t_s: float, target_position: npt.ArrayLike, target_yaw_rad: float) -> bool:
        """Move the footstep (x, y, yaw) from time ``t_s`` on, continuously; the height profile stays.

        Returns:
            False (nothing changed) when less than ``MIN_RETARGET_S`` of the horizontal motion is left.

        Raises:
            InvalidPlanningInput: A non-finite target.
        """
        left = self.horizontal_end_s - t_s
        p1 = _point("target_position", target_position)
        if left < MIN_RETARGET_S:
            return False
        p, v, a = self._plane_at(t_s)
        goal = self._goal(p[2], p1, target_yaw_rad)
        self._plane = quintic_columns(p, v, a, goal, 0.0, 0.0, left)
        self._plane_t0 = float(t_s)
        self._cache = self._plane_end_cache = self._plane_cache = None
        self.target_position = np.array([p1[0], p1[1], self.target_position[2]])
        self.target_yaw_rad = goal[2]
        return True

    def retime(self, t_s: float, duration_s: float) -> bool:
        """Touch down at ``t0_s + duration_s`` instead, from time ``t_s`` on, continuously.

        The horizontal motion (to the same footstep) is re-planned from the path's state at ``t_s`` to
        end at ``horizontal_fraction`` of the new swing (not before ``MIN_RETARGET_S`` from now), and the
        height from its state at ``t_s`` to the apex at the new swing's half (if that is still ahead by
        ``MIN_RETARGET_S``), then down to the footstep at the new end; a quicker swing so reaches its
        footstep, at rest, at its new touchdown time.

        Returns:
            False (nothing changed) when the new end is less than ``2 MIN_RETARGET_S`` from ``t_s``
            or the path has already touched down.

        Raises:
            InvalidPlanningInput: A non-positive or non-finite duration.
        """
        duration = check_time("duration_s", duration_s)
        end = self.t0_s + duration
        if end - t_s < 2.0 * MIN_RETARGET_S or t_s >= self.end_s:
            return False
        p, v, a = self._plane_at(t_s)
        tau = max(t_s - self.t0_s, 0.0)
        z, vz, az = self._height_at(tau)
        fraction = self.horizontal_fraction
        goal = [*self.target_position[:2].tolist(), self.target_yaw_rad]
        horizontal_end = min(max(self.t0_s + fraction * duration, t_s + MIN_RETARGET_S), end)
        if self.horizontal_end_s - t_s > 0.0:  # still moving: on from its state to the footstep
            self._plane = quintic_columns(p, v, a, goal, 0.0, 0.0, horizontal_end - t_s)
            self._plane_t0 = float(t_s)
        else:  # already there: it stays
            self._plane = quintic_columns(goal, 0.0, 0.0, goal, 0.0, 0.0, 1.0)
            self._plane_t0 = horizontal_end - 1.0
        self.horizontal_end_s = horizontal_end
        z1 = float(self.target_position[2])
        half = 0.5 * duration
        if half - tau >= MIN_RETARGET_S:
            self._height = [(tau, quintic_columns(z, vz, az, self._apex_m, 0.0, 0.0, half - tau)),
                            (half, quintic_columns(self._apex_m, 0.0, 0.0, z1, 0.0, 0.0, duration - half))]
        else:
            self._height = [(tau, quintic_columns(z, vz, az, z1, 0.0, 0.0, duration - tau))]
        self.duration_s = duration
        self._cache = self._plane_end_cache = self._plane_cache = None
        return True

    def _height_at(self, tau_s: float) -> tuple[float, float, float]:
        """The height [m], its rate and acceleration ``tau_s`` [s] after lift-off (on its pieces)."""
        start, columns = self._height[0]
        for piece_start, piece in self._height[1:]:
            if tau_s <= piece_start:
                break
            start, columns = piece_start, piece
        (z,), (vz,), (az,) = quintic_columns_at(columns, tau_s - start)
        return z, vz, az

    def at(self, t_s: float) -> SwingSample:
        """The reference at time ``t_s`` [s] (held at the ends outside the swing; the caller may edit it)."""
        cached = self._cache
        if cached is None or cached[0] != t_s:
            cached = self._cache = (t_s, self._at(t_s))
        p, v, a, *rest = cached[1]  # new arrays each call: the caller may edit them
        return SwingSample(np.array(p), np.array(v), np.array(a), *rest)

    def yaw_at(self, t_s: float) -> float:
        """The yaw reference [rad] at time ``t_s`` [s] (``at(t_s).yaw_rad``, without copying the sample)."""
        cached = self._cache
        if cached is not None and cached[0] == t_s:
            return cached[1][3]
        return self._plane_at(t_s)[0][2]

    def _plane_at(self, t_s: float) -> tuple[list[float], list[float], list[float]]:
        """(x, y, yaw), their rates and accelerations at ``t_s`` (kept for the same time and path)."""
        if t_s >= self.horizontal_end_s:  # at the footstep (x, y, yaw): the same until a retarget
            if self._plane_end_cache is None:
                end = max(0.0, self.horizontal_end_s - self._plane_t0)
                self._plane_end_cache = quintic_columns_at(self._plane, end)[0]
            return self._plane_end_cache, [0.0] * 3, [0.0] * 3
        cached = self._plane_cache
        if cached is None or cached[0] != t_s:
            tau = max(0.0, t_s - self._plane_t0)
            cached = self._plane_cache = (t_s, quintic_columns_at(self._plane, tau))
        return cached[1]

    def _at(self, t_s: float) -> tuple:
        """:meth:`at`'s fields as floats (position, velocity and acceleration as (x, y, z) lists)."""
        tau = min(max(t_s - self.t0_s, 0.0), self.duration_s)
        p, v, a = self._plane_at(t_s)
        z, vz, az = self._height_at(tau)
        if t_s <= self.t0_s or t_s >= self.end_s:  # at rest outside the swing
            v, a, vz, az = [0.0] * 3, [0.0] * 3, 0.0, 0.0
        return [p[0], p[1], z], [v[0], v[1], vz], [a[0], a[1], az], p[2], v[2], tau / self.duration_s, a[2]


def _point(label: str, value: npt.ArrayLike) -> np.ndarray:
    arr = np.array(value, dtype=float)
    if arr.shape != (3,) or not all(map(math.isfinite, arr.tolist())):
        raise InvalidPlanningInput(f"{label} must be a finite (3,) position [m] in W; got {value!r}")
    return arr
