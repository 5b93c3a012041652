"""Cubic, quintic and minimum-jerk joint trajectories between two states over a fixed duration.

With ``tau = t / T`` in 0..1 and ``dq = q1 - q0``, each joint follows a polynomial in t whose
coefficients solve the boundary conditions at t = 0 and t = T:

- cubic: ``q(0) = q0, qd(0) = v0, q(T) = q1, qd(T) = v1`` (accelerations are not matched);
- quintic: the cubic conditions plus ``qdd(0) = a0, qdd(T) = a1``;
- minimum jerk (Flash and Hogan 1985): the quintic at rest at both ends,
  ``q = q0 + dq (10 tau^3 - 15 tau^4 + 6 tau^5)``, the motion minimising the integral of the
  squared jerk; its velocity is symmetric about ``T / 2`` and peaks there at ``1.875 dq / T``.

No limits are enforced: the duration sets the speed. The duration is rounded up to a whole
number of control periods so that the samples lie on a uniform grid; the boundary conditions
hold exactly at the (rounded) last sample.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from mbctl.planners._validation import check_boundary_states, check_names, check_time
from mbctl.planners.exceptions import PlanningError
from mbctl.planners.trajectory import JointTrajectory

#: Relative tolerance [-] under which ``duration_s / dt_s`` counts as a whole number of periods
#: (so 1.0 s at 0.01 s gives 100 periods, not 101, despite round-off).
PERIOD_RTOL = 1e-9


#: Relative mismatch [-] between the evaluated polynomial at T and the boundary value above
#: which the end is not snapped but reported (it would mean ill-conditioned coefficients).
END_RTOL = 1e-9


def cubic_trajectory(
    current_position: npt.ArrayLike,
    target_position: npt.ArrayLike,
    duration_s: float,
    dt_s: float,
    names: Sequence[str],
    current_velocity: npt.ArrayLike | None = None,
    target_velocity: npt.ArrayLike | None = None,
) -> JointTrajectory:
    """A cubic polynomial per joint matching position and velocity at both ends.

    Args:
        current_position: Start positions (n,) [rad].
        target_position: Goal positions (n,) [rad].
        duration_s: Duration T [s] (> 0), rounded up to a multiple of ``dt_s``.
        dt_s: Control period [s].
        names: Joint names of the n DoFs.
        current_velocity: Start velocities (n,) [rad/s]; zero if None.
        target_velocity: Goal velocities (n,) [rad/s]; zero if None.

    Returns:
        Samples at ``0, dt_s, ..., T``; the accelerations jump at the ends (a cubic cannot match
        them).

    Raises:
        InvalidPlanningInput: Wrong shapes, non-finite values, or a non-positive duration or
            period.
        PlanningError: The evaluated end state misses the boundary values beyond round-off.
    """
    names = check_names(names)
    q0, q1, v0, v1, _, _ = check_boundary_states(
        len(names), current_position, target_position, current_velocity, target_velocity
    )
    t, T = _grid(duration_s, dt_s)
    # q(t) = q0 + v0 t + c2 t^2 + c3 t^3.
    dq = q1 - q0
    c2 = (3.0 * dq - (2.0 * v0 + v1) * T) / T**2
    c3 = (-2.0 * dq + (v0 + v1) * T) / T**3
    coeffs = np.vstack([q0, v0, c2, c3])
    q, v, a = _evaluate(coeffs, t)
    _snap_end(q, q1, "position")
    _snap_end(v, v1, "velocity")
    return JointTrajectory(t, q, v, a, names)


def quintic_trajectory(
    current_position: npt.ArrayLike,
    target_position: npt.ArrayLike,
    duration_s: float,
    dt_s: float,
    names: Sequence[str],
    current_velocity: npt.ArrayLike | None = None,
    target_velocity: npt.ArrayLike | None = None,
    current_acceleration: npt.ArrayLike | None = None,
    target_acceleration: npt.ArrayLike | None = None,
) -> JointTrajectory:
    """A quintic polynomial per joint matching position, velocity and acceleration at both ends.

    Args:
        current_position: Start positions (n,) [rad].
        target_position: Goal positions (n,) [rad].
        duration_s: Duration T [s] (> 0), rounded up to a multiple of ``dt_s``.
        dt_s: Control period [s].
        names: Joint names of the n DoFs.
        current_velocity: Start velocities (n,) [rad/s]; zero if None.
        target_velocity: Goal velocities (n,) [rad/s]; zero if None.
        current_acceleration: Start accelerations (n,) [rad/s^2]; zero if None.
        target_acceleration: Goal accelerations (n,) [rad/s^2]; zero if None.

    Returns:
        Samples at ``0, dt_s, ..., T``.

    Raises:
        InvalidPlanningInput: Wrong shapes, non-finite values, or a non-positive duration or
            period.
        PlanningError: The evaluated end state misses the boundary values beyond round-off.
    """
    names = check_names(names)
    q0, q1, v0, v1, a0, a1 = check_boundary_states(
        len(names), current_position, target_position, current_velocity, target_velocity,
        current_acceleration, target_acceleration,
    )
    t, T = _grid(duration_s, dt_s)
    # q(t) = q0 + v0 t + a0/2 t^2 + c3 t^3 + c4 t^4 + c5 t^5, the standard closed form.
    dq = q1 - q0
    c3 = (20.0 * dq - (8.0 * v1 + 12.0 * v0) * T - (3.0 * a0 - a1) * T**2) / (2.0 * T**3)
    c4 = (-30.0 * dq + (14.0 * v1 + 16.0 * v0) * T + (3.0 * a0 - 2.0 * a1) * T**2) / (2.0 * T**4)
    c5 = (12.0 * dq - 6.0 * (v1 + v0) * T - (a0 - a1) * T**2) / (2.0 * T**5)
    coeffs = np.vstack([q0, v0, 0.5 * a0, c3, c4, c5])
    q, v, a = _evaluate(coeffs, t)
    _snap_end(q, q1, "position")
    _snap_end(v, v1, "velocity")
    _snap_end(a, a1, "acceleration")
    return JointTrajectory(t, q, v, a, names)


def minimum_jerk_trajectory(
    current_position: npt.ArrayLike,
    target_position: npt.ArrayLike,
    duration_s: float,
    dt_s: float,
    names: Sequence[str],
) -> JointTrajectory:
    """The minimum-jerk rest-to-rest motion ``q0 + dq (10 tau^3 - 15 tau^4 + 6 tau^5)``.

    Args:
        current_position: Start positions (n,) [rad].
        target_position: Goal positions (n,) [rad].
        duration_s: Duration T [s] (> 0), rounded up to a multiple of ``dt_s``.
        dt_s: Control period [s].
        names: Joint names of the n DoFs.

    Returns:
        Samples at ``0, dt_s, ..., T``, at rest (zero velocity and acceleration) at both ends.

    Raises:
        InvalidPlanningInput: Wrong shapes, non-finite values, or a non-positive duration or
            period.
    """
    return quintic_trajectory(current_position, target_position, duration_s, dt_s, names)


def minimum_jerk_at(
    start: npt.ArrayLike, goal: npt.ArrayLike, t_s: float, t0_s: float, duration_s: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The minimum-jerk blend from ``start`` to ``goal`` over ``[t0_s, t0_s + duration_s]``, at ``t_s``.

    For evaluating one time per control cycle (a scenario's targets) without sampling a whole
    trajectory; before ``t0_s`` it holds ``start``, after the end ``goal``, at rest.

    Args:
        start: Start position (n,) (any unit).
        goal: Goal position (n,).
        t_s: Evaluation time [s].
        t0_s: Start of the motion [s].
        duration_s: Duration T [s] (> 0).

    Returns:
        Position (n,), velocity (n,) [unit/s] and acceleration (n,) [unit/s^2] at ``t_s``.

    Raises:
        InvalidPlanningInput: A non-positive or non-finite duration.
    """
    T = check_time("duration_s", duration_s)
    if t_s < t0_s or t_s > t0_s + T:  # at rest: the end held (no arithmetic: this runs every cycle)
        held = np.array(start if t_s < t0_s else goal, dtype=float)
        zero = np.zeros_like(held)
        return held, zero, zero.copy()
    a, b = np.asarray(start, dtype=float), np.asarray(goal, dtype=float)
    d = b - a
    tau = (t_s - t0_s) / T
    s = tau**3 * (10.0 - 15.0 * tau + 6.0 * tau * tau)
    ds = 30.0 * tau * tau * (1.0 - tau) ** 2
    dds = 60.0 * tau * (1.0 - tau) * (1.0 - 2.0 * tau)
    return a + s * d, d * (ds / T), d * (dds / T**2)


def _grid(duration_s: float, dt_s: float) -> tuple[np.ndarray, float]:
    """Uniform times ``0..T`` and ``T``: the duration rounded up to whole periods."""
    dt = check_time("dt_s", dt_s)
    periods = check_time("duration_s", duration_s) / dt
    n_steps = max(1, int(math.ceil(periods * (1.0 - PERIOD_RTOL))))
    t = np.arange(n_steps + 1) * dt
    return t, float(t[-1])


def _snap_end(samples: np.ndarray, target: np.ndarray, label: str) -> None:
    """Set the last sample to the boundary value after checking it agrees to round-off."""
    err = float(np.max(np.abs(samples[-1] - target)))
    scale = max(1.0, float(np.max(np.abs(samples))))
    if err > END_RTOL * scale:
        raise PlanningError(
            f"polynomial end {label} misses the boundary value by {err:.3g} (> {END_RTOL:g} "
            "relative); the duration is probably too short for the round-off of t^5"
        )
    samples[-1] = target


def _evaluate(coeffs: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position, velocity and acceleration of ``sum_k coeffs[k] t^k`` (coeffs (K, n))."""
    powers = np.arange(coeffs.shape[0])
    tp = t[:, None] ** powers  # (N, K)
    q = tp @ coeffs
    dcoeffs = coeffs[1:] * powers[1:, None]
    v = (t[:, None] ** powers[:-1]) @ dcoeffs
    ddcoeffs = dcoeffs[1:] * powers[1:-1, None]
    a = (t[:, None] ** powers[:-2]) @ ddcoeffs
    return q, v, a
