"""Input checks shared by the joint-space planners (names, periods, boundary states, waypoints).

Each check raises ``InvalidPlanningInput`` with a message that names the argument, the offending
value or shape, and what is allowed.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from mbctl.planners.exceptions import InvalidPlanningInput


def check_names(names: Sequence[str]) -> tuple[str, ...]:
    """Joint names as a tuple: a non-empty sequence of unique strings (not a bare string)."""
    if isinstance(names, str):
        raise InvalidPlanningInput(f"names must be a sequence of joint names; got the string "
                                   f"{names!r}")
    out = tuple(names)
    if not out or not all(isinstance(x, str) for x in out):
        raise InvalidPlanningInput(f"names must be a non-empty sequence of strings; got {names!r}")
    if len(set(out)) != len(out):
        raise InvalidPlanningInput(f"names must be unique; got {out}")
    return out


def check_time(label: str, value: float) -> float:
    """A time such as ``dt_s`` or ``duration_s`` [s] as a float: a finite number > 0."""
    try:
        out = float(value)
    except (TypeError, ValueError) as exc:
        raise InvalidPlanningInput(f"{label} must be a number [s]; got {value!r}") from exc
    if not (math.isfinite(out) and out > 0.0):
        raise InvalidPlanningInput(f"{label} must be finite and > 0 [s]; got {value!r}")
    return out


def check_state(label: str, value: npt.ArrayLike | None, n: int) -> np.ndarray:
    """A finite (n,) state vector; zeros if ``value`` is None."""
    if value is None:
        return np.zeros(n)
    arr = np.asarray(value, dtype=float)
    if arr.shape != (n,):
        raise InvalidPlanningInput(f"{label} must have shape ({n},); got {arr.shape}")
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        i = int(bad[0])
        raise InvalidPlanningInput(f"{label}[{i}] = {float(arr[i])!r} (DoF {i}) must be finite")
    return arr


def check_boundary_states(
    n: int,
    current_position: npt.ArrayLike,
    target_position: npt.ArrayLike,
    current_velocity: npt.ArrayLike | None = None,
    target_velocity: npt.ArrayLike | None = None,
    current_acceleration: npt.ArrayLike | None = None,
    target_acceleration: npt.ArrayLike | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The start and goal states of a state-to-state planner, checked in argument order.

    Returns:
        ``(q0, q1, v0, v1, a0, a1)``, each (n,); a missing velocity or acceleration is zero.
    """
    return (
        check_state("current_position", current_position, n),
        check_state("target_position", target_position, n),
        check_state("current_velocity", current_velocity, n),
        check_state("target_velocity", target_velocity, n),
        check_state("current_acceleration", current_acceleration, n),
        check_state("target_acceleration", target_acceleration, n),
    )


def check_matrix(label: str, value: npt.ArrayLike, n: int) -> np.ndarray:
    """A finite (K, n) array of K joint-space rows."""
    arr = np.asarray(value, dtype=float)
    if arr.ndim != 2 or arr.shape[1] != n:
        raise InvalidPlanningInput(f"{label} must have shape (K, {n}); got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        row, col = (int(x) for x in np.argwhere(~np.isfinite(arr))[0])
        raise InvalidPlanningInput(f"{label}[{row}, {col}] = {float(arr[row, col])!r} must be finite")
    return arr


def check_waypoints(waypoints: npt.ArrayLike, n: int) -> np.ndarray:
    """Waypoints (K, n) [rad] with K >= 2 (a start and a goal)."""
    wps = check_matrix("waypoints", waypoints, n)
    if wps.shape[0] < 2:
        raise InvalidPlanningInput(
            f"waypoints needs at least 2 rows (start and goal); got {wps.shape[0]}"
        )
    return wps
