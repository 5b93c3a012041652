"""Jerk-limited, time-synchronized state-to-state joint trajectories with ruckig (offline, local).

For each DoF ``i`` ruckig finds a piecewise-constant-jerk profile from the current state
``(q0_i, v0_i, a0_i)`` to the target state ``(q1_i, v1_i, a1_i)`` with

    |v_i(t)| <= max_velocity_i,  |a_i(t)| <= max_acceleration_i,  |j_i(t)| <= max_jerk_i,

and stretches the faster DoFs so that all DoFs arrive at the same time (time synchronization).
The duration is rounded up to a whole number of control periods ``dt_s`` (ruckig's discrete
duration mode), so the samples lie on a uniform grid whose last sample is exactly the end.

Only ruckig's local state-to-state calculation is used; its cloud (waypoint) API never is.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from ruckig import (
    DurationDiscretization,
    InputParameter,
    Result,
    Ruckig,
    RuckigError,
    Synchronization,
    Trajectory,
)

from mbctl.planners._validation import (
    check_boundary_states,
    check_matrix,
    check_names,
    check_time,
    check_waypoints,
)
from mbctl.planners.exceptions import (
    InvalidLimits,
    InvalidPlanningInput,
    TrajectoryGenerationFailed,
)
from mbctl.planners.trajectory import JointTrajectory

#: Largest mismatch [rad] or [rad/s] or [rad/s^2] accepted between ruckig's end state and the
#: requested target before the last sample is snapped to the target exactly.
END_STATE_ATOL = 1e-8

#: Scale factors [-] applied to all limits on successive attempts. Ruckig 0.19 rejects some
#: inputs that sit exactly on a boundary between profile types (e.g. a 0.02000000000000002 rad
#: move with max_velocity 0.25, max_acceleration 1, max_jerk 10, where the jerk-only profile
#: just reaches max_acceleration); slightly tighter limits move the input off the boundary and
#: still respect the requested limits.
RETRY_LIMIT_FACTORS = (1.0, 1.0 - 1e-9, 1.0 - 1e-6)

_LIMIT_UNITS = {
    "max_velocity": "rad/s",
    "max_acceleration": "rad/s^2",
    "max_jerk": "rad/s^3",
}


@dataclass(frozen=True)
class JointLimits:
    """Per-joint kinematic limits (symmetric: ``-max <= x <= max``).

    Attributes:
        max_velocity: Velocity limits (n,) [rad/s] (or [m/s] for prismatic joints), > 0.
        max_acceleration: Acceleration limits (n,) [rad/s^2], > 0.
        max_jerk: Jerk limits (n,) [rad/s^3], > 0.

    The arrays are read-only copies.

    Raises:
        InvalidLimits: An array is not 1-D, the three lengths differ, or an entry is not
            positive and finite (the message names the quantity, the DoF index and the value).
    """

    max_velocity: np.ndarray
    max_acceleration: np.ndarray
    max_jerk: np.ndarray

    def __post_init__(self) -> None:
        """Validate and freeze the arrays."""
        n_dofs = None
        for name in ("max_velocity", "max_acceleration", "max_jerk"):
            try:
                arr = np.array(getattr(self, name), dtype=float)
            except (TypeError, ValueError) as exc:
                raise InvalidLimits(f"{name} must be an array of numbers; got {exc}") from exc
            if arr.ndim != 1 or arr.size == 0:
                raise InvalidLimits(
                    f"{name} must be a non-empty 1-D array (one entry per DoF); got shape "
                    f"{arr.shape}"
                )
            if n_dofs is None:
                n_dofs = arr.size
            elif arr.size != n_dofs:
                raise InvalidLimits(
                    f"{name} has {arr.size} entries but max_velocity has {n_dofs}; give one "
                    "limit per DoF"
                )
            for i, value in enumerate(arr):
                if not (np.isfinite(value) and value > 0.0):
                    raise InvalidLimits(
                        f"{name}[{i}] = {float(value)!r} {_LIMIT_UNITS[name]} (DoF {i}) must be finite "
                        "and > 0"
                    )
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    @classmethod
    def uniform(
        cls, dofs: int, max_velocity: float, max_acceleration: float, max_jerk: float
    ) -> JointLimits:
        """The same limits for every DoF.

        Args:
            dofs: Number of DoFs (>= 1).
            max_velocity: Velocity limit [rad/s].
            max_acceleration: Acceleration limit [rad/s^2].
            max_jerk: Jerk limit [rad/s^3].

        Raises:
            InvalidLimits: ``dofs`` < 1 or a limit is not positive and finite.
        """
        if int(dofs) < 1:
            raise InvalidLimits(f"dofs must be >= 1; got {dofs!r}")
        n = int(dofs)
        return cls(
            np.full(n, float(max_velocity)),
            np.full(n, float(max_acceleration)),
            np.full(n, float(max_jerk)),
        )

    @property
    def dofs(self) -> int:
        """Number of DoFs."""
        return int(self.max_velocity.size)


def plan_ruckig(
    current_position: npt.ArrayLike,
    target_position: npt.ArrayLike,
    limits: JointLimits,
    dt_s: float,
    names: Sequence[str],
    current_velocity: npt.ArrayLike | None = None,
    target_velocity: npt.ArrayLike | None = None,
    current_acceleration: npt.ArrayLike | None = None,
    target_acceleration: npt.ArrayLike | None = None,
    minimum_duration_s: float | None = None,
) -> JointTrajectory:
    """A jerk-limited, time-synchronized trajectory from the current to the target state.

    Args:
        current_position: Start positions (n,) [rad].
        target_position: Goal positions (n,) [rad].
        limits: Velocity, acceleration and jerk limits for the n DoFs.
        dt_s: Control period [s] (> 0); the sample step of the result.
        names: Joint names of the n DoFs.
        current_velocity: Start velocities (n,) [rad/s]; zero if None.
        target_velocity: Goal velocities (n,) [rad/s]; zero if None. Must be within the limits.
        current_acceleration: Start accelerations (n,) [rad/s^2]; zero if None.
        target_acceleration: Goal accelerations (n,) [rad/s^2]; zero if None.
        minimum_duration_s: If given, the trajectory lasts at least this long [s].

    Returns:
        Samples at ``t = 0, dt_s, ..., T`` with ``T`` the synchronized duration rounded up to a
        whole number of periods; the last sample is exactly the target state. If the start
        already equals the target (to ruckig's round-off) the result is a single sample holding
        the target state.

    Raises:
        InvalidPlanningInput: Wrong shapes, non-finite states, bad ``dt_s``, names or
            ``minimum_duration_s``.
        InvalidLimits: ``limits`` has a different number of DoFs than the positions.
        TrajectoryGenerationFailed: Ruckig rejected the input (e.g. a target velocity above
            ``max_velocity``) or found no trajectory.
    """
    names = check_names(names)
    n = len(names)
    dt = check_time("dt_s", dt_s)
    q0, q1, v0, v1, a0, a1 = check_boundary_states(
        n, current_position, target_position, current_velocity, target_velocity,
        current_acceleration, target_acceleration,
    )
    if limits.dofs != n:
        raise InvalidLimits(
            f"limits cover {limits.dofs} DoFs but the trajectory has {n} joints {names}"
        )
    for label, value, bound, unit in (
        ("target_velocity", v1, limits.max_velocity, "rad/s"),
        ("target_acceleration", a1, limits.max_acceleration, "rad/s^2"),
    ):
        over = np.flatnonzero(np.abs(value) > bound)
        if over.size:
            i = int(over[0])
            raise TrajectoryGenerationFailed(
                f"{label}[{i}] = {float(value[i])!r} {unit} (DoF {i}, {names[i]!r}) exceeds the limit "
                f"{float(bound[i])!r} {unit}; a target state must lie within the limits",
                "ErrorInvalidInput",
            )

    if minimum_duration_s is not None and not (
        np.isfinite(minimum_duration_s) and minimum_duration_s >= 0.0
    ):
        raise InvalidPlanningInput(
            f"minimum_duration_s must be finite and >= 0 [s]; got {minimum_duration_s!r}"
        )
    traj, error = None, None
    for factor in RETRY_LIMIT_FACTORS:
        try:
            traj = _calculate(q0, v0, a0, q1, v1, a1, limits, factor, dt, minimum_duration_s)
            break
        except (RuckigError, _ResultError) as exc:
            error = exc
    if traj is None:
        details = str(error).strip()
        raise TrajectoryGenerationFailed(
            f"ruckig found no trajectory for {names} from {q0.tolist()} to {q1.tolist()} rad: "
            f"{details.splitlines()[0] if details else 'no details'}. Check that the limits are "
            "reasonable for the distance (very large moves or tiny limits overflow).",
            getattr(error, "result", "RuckigError"),
            details,
        ) from error
    duration = float(traj.duration)
    n_steps = max(int(round(duration / dt)), 0)
    t = np.arange(n_steps + 1) * dt
    q = np.empty((n_steps + 1, n))
    v = np.empty_like(q)
    a = np.empty_like(q)
    for k, tk in enumerate(t):
        pos, vel, acc = traj.at_time(min(float(tk), duration))
        q[k], v[k], a[k] = pos, vel, acc
    for label, got, want in (("position", q[-1], q1), ("velocity", v[-1], v1),
                             ("acceleration", a[-1], a1)):
        err = float(np.max(np.abs(got - want)))
        if err > END_STATE_ATOL * max(1.0, float(np.max(np.abs(want)))):
            raise TrajectoryGenerationFailed(
                f"ruckig's end {label} misses the target by {err:.3g}; expected <= "
                f"{END_STATE_ATOL:g}",
                "EndStateMismatch",
            )
    # Ruckig's end state agrees to round-off; make it exact.
    q[-1], v[-1], a[-1] = q1, v1, a1
    return JointTrajectory(t, q, v, a, names)


class _ResultError(Exception):
    """Internal: ruckig returned an error ``Result`` (kept by name in ``result``)."""

    def __init__(self, result: str):
        self.result = result
        super().__init__(f"ruckig returned Result.{result}")


def _calculate(
    q0: np.ndarray,
    v0: np.ndarray,
    a0: np.ndarray,
    q1: np.ndarray,
    v1: np.ndarray,
    a1: np.ndarray,
    limits: JointLimits,
    factor: float,
    dt: float,
    minimum_duration_s: float | None,
) -> Trajectory:
    """One ruckig calculation with the limits scaled by ``factor`` (<= 1).

    Raises:
        RuckigError: Ruckig rejected the input (the bindings raise).
        _ResultError: Ruckig returned an error code instead of raising.
    """
    n = q0.size
    otg = Ruckig(n, dt)
    inp = InputParameter(n)
    inp.current_position = q0.tolist()
    inp.current_velocity = v0.tolist()
    inp.current_acceleration = a0.tolist()
    inp.target_position = q1.tolist()
    inp.target_velocity = v1.tolist()
    inp.target_acceleration = a1.tolist()
    # Tightened limits must still admit the target state (checked against the unscaled ones).
    inp.max_velocity = np.maximum(limits.max_velocity * factor, np.abs(v1)).tolist()
    inp.max_acceleration = np.maximum(limits.max_acceleration * factor, np.abs(a1)).tolist()
    inp.max_jerk = (limits.max_jerk * factor).tolist()
    inp.synchronization = Synchronization.Time
    inp.duration_discretization = DurationDiscretization.Discrete
    if minimum_duration_s is not None:
        inp.minimum_duration = float(minimum_duration_s)
    traj = Trajectory(n)
    result = otg.calculate(inp, traj)
    if result not in (Result.Working, Result.Finished):
        raise _ResultError(result.name)
    return traj


def plan_waypoints(
    waypoints: npt.ArrayLike,
    limits: JointLimits,
    dt_s: float,
    names: Sequence[str],
    waypoint_velocities: npt.ArrayLike | None = None,
) -> JointTrajectory:
    """A trajectory through joint-space waypoints by chaining state-to-state ruckig segments.

    By default the robot comes to rest at each waypoint (zero velocity and acceleration). With
    ``waypoint_velocities`` it passes each waypoint at the given velocity instead (zero
    acceleration there); each segment still respects the limits and hits its waypoint exactly,
    but the path between waypoints may overshoot if the velocities point the wrong way.

    Args:
        waypoints: Positions (K, n) [rad], K >= 2; the first row is the start state.
        limits: Limits for the n DoFs.
        dt_s: Control period [s].
        names: Joint names of the n DoFs.
        waypoint_velocities: Optional velocities (K, n) [rad/s] at each waypoint (the first row
            is the start velocity). The last row is normally zero.

    Returns:
        One trajectory on a uniform grid; every waypoint is a sample, exactly.

    Raises:
        InvalidPlanningInput: ``waypoints`` or ``waypoint_velocities`` has the wrong shape or
            non-finite entries.
        InvalidLimits: ``limits`` has a different number of DoFs.
        TrajectoryGenerationFailed: Ruckig failed on a segment (the message names it).
    """
    names = check_names(names)
    n = len(names)
    wps = check_waypoints(waypoints, n)
    if waypoint_velocities is None:
        vels = np.zeros_like(wps)
    else:
        vels = check_matrix("waypoint_velocities", waypoint_velocities, n)
        if vels.shape != wps.shape:
            raise InvalidPlanningInput(
                f"waypoint_velocities must have the shape of waypoints {wps.shape}; got "
                f"{vels.shape}"
            )
    segments = []
    for k in range(wps.shape[0] - 1):
        try:
            segments.append(plan_ruckig(wps[k], wps[k + 1], limits, dt_s, names,
                                        current_velocity=vels[k], target_velocity=vels[k + 1]))
        except TrajectoryGenerationFailed as exc:
            raise TrajectoryGenerationFailed(
                f"segment {k} (waypoint {k} -> {k + 1}): {exc}", exc.result, exc.details
            ) from exc
    return concatenate(segments)


def pass_through_velocities(
    waypoints: npt.ArrayLike, limits: JointLimits, dt_s: float, names: Sequence[str]
) -> np.ndarray:
    """Heuristic velocities for passing through waypoints without stopping.

    For each interior waypoint k and DoF i, with ``d_prev`` and ``d_next`` the displacements of
    the adjacent segments and ``T_prev``, ``T_next`` their rest-to-rest ruckig durations, the
    velocity is the mean of the two average segment velocities,
    ``0.5 (d_prev / T_prev + d_next / T_next)``, if both move the same way, else 0 (the DoF
    reverses there, so it should stop). The first and last rows are zero. The values are within
    ``max_velocity`` (an average velocity cannot exceed it). Pass them to ``plan_waypoints``.

    Args:
        waypoints: Positions (K, n) [rad], K >= 2.
        limits: Limits for the n DoFs.
        dt_s: Control period [s] (used for the rest-to-rest duration estimates).
        names: Joint names of the n DoFs.

    Returns:
        Velocities (K, n) [rad/s].

    Raises:
        InvalidPlanningInput: Bad shapes or values.
        InvalidLimits: ``limits`` has a different number of DoFs.
        TrajectoryGenerationFailed: Ruckig failed on a rest-to-rest estimate.
    """
    names = check_names(names)
    wps = check_waypoints(waypoints, len(names))
    d = np.diff(wps, axis=0)
    durations = np.array([
        plan_ruckig(wps[k], wps[k + 1], limits, dt_s, names).duration_s for k in range(len(d))
    ])
    mean_v = np.divide(d, durations[:, None], out=np.zeros_like(d),
                       where=durations[:, None] > 0.0)
    vels = np.zeros_like(wps)
    same_way = np.sign(d[:-1]) * np.sign(d[1:]) > 0.0
    vels[1:-1] = np.where(same_way, 0.5 * (mean_v[:-1] + mean_v[1:]), 0.0)
    return np.clip(vels, -limits.max_velocity, limits.max_velocity)


def concatenate(segments: Sequence[JointTrajectory]) -> JointTrajectory:
    """Segments played one after the other, each starting exactly at the previous end state.

    The shared boundary sample is kept once. Unlike ``JointTrajectory.then`` this also drops
    it when the robot passes a waypoint at non-zero velocity, and it joins all segments in one
    allocation.

    Args:
        segments: Trajectories over the same names and with the same ``dt_s``.

    Raises:
        InvalidPlanningInput: No segments, different names or different sample periods.
    """
    if not segments:
        raise InvalidPlanningInput("concatenate needs at least one segment")
    first = segments[0]
    t = [first.t_s]
    rows = {"q": [first.q], "v": [first.v], "a": [first.a]}
    for k, seg in enumerate(segments[1:], start=1):
        if seg.names != first.names:
            raise InvalidPlanningInput(
                f"segment {k} is over joints {seg.names}, segment 0 over {first.names}"
            )
        if len(seg.t_s) > 1 and len(first.t_s) > 1 and not np.isclose(seg.dt_s, first.dt_s):
            raise InvalidPlanningInput(
                f"segment {k} has dt_s = {seg.dt_s!r} s, segment 0 has {first.dt_s!r} s"
            )
        t.append(seg.t_s[1:] - seg.t_s[0] + t[-1][-1])
        for key in rows:
            rows[key].append(getattr(seg, key)[1:])
    return JointTrajectory(np.concatenate(t), np.vstack(rows["q"]), np.vstack(rows["v"]),
                           np.vstack(rows["a"]), first.names)

