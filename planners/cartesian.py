"""Cartesian paths (line, circle, polyline/square), a jerk-limited timing law, and joint conversion.

Notation: a path is a curve ``p(s)`` (3,) [m] in the world frame W, parameterised by arc length
``s`` in ``0..L`` [m], with unit tangent ``t(s) = dp/ds`` and curvature vector
``k(s) = d2p/ds2`` [1/m]. A timing law ``s(t)`` turns it into a trajectory:

    v(t) = t(s) s_dot,        a(t) = t(s) s_ddot + k(s) s_dot^2.

The timing law is a 1-DoF ruckig trajectory on ``s`` with limits on the path speed, the
tangential acceleration and the jerk of ``s``. A path with a sharp corner cannot be tracked at
non-zero speed with bounded acceleration (the velocity direction would jump), so the timing law
comes to rest at every corner: each smooth section is timed rest-to-rest on its own.

The limits bound ``s_dot``, ``s_ddot`` and ``s_dddot`` only. On a curved section the Cartesian
acceleration also has the normal part ``|k| s_dot^2`` (``s_dot^2 / r`` on a circle of radius r);
choose ``max_speed <= sqrt(a_normal_max r)`` if that must be bounded too.

Joint conversion (``to_joint_trajectory``): q from the caller's IK at each sample,
``qd = J^+ v`` and ``qdd = J^+ (a - Jdot qd)``, with J the caller's position Jacobian (m, n)
(m = 2 for a planar arm using x-y, m = 3 for x-y-z).
"""

from __future__ import annotations

import abc
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from mbctl.planners._validation import check_names, check_time
from mbctl.planners.exceptions import (
    InvalidLimits,
    InvalidPath,
    InvalidPlanningInput,
    PathIKFailed,
    PathNotTrackable,
)
from mbctl.planners.ruckig_planner import JointLimits, concatenate, plan_ruckig
from mbctl.planners.trajectory import JointTrajectory, _UniformGrid

#: Relative step [-] of the central difference of J along qd used when no ``jacobian_dot`` is
#: given: the joint displacement is ``h |qd| = FD_JOINT_STEP`` [rad].
FD_JOINT_STEP = 1e-6

#: Relative tolerance [-] on ``|J qd - v|`` and ``|J qdd + Jdot qd - a|`` (relative to the
#: largest of 1 and the Cartesian magnitude) before a sample counts as not trackable.
TRACKING_RTOL = 1e-8

#: Tolerance [m] on the motion along Cartesian axes that a (m < 3)-row Jacobian ignores.
IGNORED_AXIS_ATOL = 1e-12


# ---------------------------------------------------------------------------------- limits
@dataclass(frozen=True)
class PathLimits:
    """Limits of the timing law on the path parameter s (arc length).

    Attributes:
        max_speed: Path speed limit ``|s_dot|`` [m/s], > 0.
        max_acceleration: Tangential acceleration limit ``|s_ddot|`` [m/s^2], > 0.
        max_jerk: Path jerk limit ``|s_dddot|`` [m/s^3], > 0.

    Raises:
        InvalidLimits: A limit is not positive and finite (the message names it and the value).
    """

    max_speed: float
    max_acceleration: float
    max_jerk: float

    def __post_init__(self) -> None:
        """Validate: each limit positive and finite."""
        for name, unit in (("max_speed", "m/s"), ("max_acceleration", "m/s^2"),
                           ("max_jerk", "m/s^3")):
            value = getattr(self, name)
            try:
                value = float(value)
            except (TypeError, ValueError) as exc:
                raise InvalidLimits(f"{name} must be a number [{unit}]; got {value!r}") from exc
            if not (math.isfinite(value) and value > 0.0):
                raise InvalidLimits(f"{name} = {value!r} {unit} must be finite and > 0")
            object.__setattr__(self, name, value)

    def as_joint_limits(self) -> JointLimits:
        """The same limits as a 1-DoF JointLimits on s."""
        return JointLimits(
            np.array([self.max_speed]), np.array([self.max_acceleration]), np.array([self.max_jerk])
        )


# ---------------------------------------------------------------------------------- paths
class CartesianPath(abc.ABC):
    """Base class of arc-length parameterised paths ``p(s)``, s in 0..length [m].

    Subclasses implement ``length``, ``corners`` and the vectorised ``_evaluate``.
    """

    @property
    @abc.abstractmethod
    def length(self) -> float:
        """Total arc length L [m]."""

    @property
    def corners(self) -> tuple[float, ...]:
        """Arc lengths [m] where the timing law must stop: 0, each sharp corner, and L."""
        return (0.0, self.length)

    @abc.abstractmethod
    def _evaluate(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, tangent and curvature vector (N, 3) each at valid arc lengths ``s`` (N,)."""

    def evaluate(self, s: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, unit tangent and curvature vector at arc lengths ``s``.

        Args:
            s: Arc lengths (N,) [m] in 0..length (a scalar gives (3,) outputs).

        Returns:
            ``p`` (N, 3) [m], ``t = dp/ds`` (N, 3) [-], ``k = d2p/ds2`` (N, 3) [1/m]. At a sharp
            corner the tangent and curvature of the following section are returned.

        Raises:
            InvalidPath: An ``s`` outside ``0..length`` (beyond a 1e-12 relative tolerance).
        """
        arr = np.asarray(s, dtype=float)
        scalar = arr.ndim == 0
        arr = np.atleast_1d(arr)
        tol = 1e-12 * max(1.0, self.length)
        if np.any(~np.isfinite(arr)) or np.any(arr < -tol) or np.any(arr > self.length + tol):
            bad = arr[~((arr >= -tol) & (arr <= self.length + tol))][0]
            raise InvalidPath(f"path parameter s = {float(bad)!r} m is outside 0..{self.length!r} m")
        p, t, k = self._evaluate(np.clip(arr, 0.0, self.length))
        if scalar:
            return p[0], t[0], k[0]
        return p, t, k

    def position(self, s: npt.ArrayLike) -> np.ndarray:
        """Position ``p(s)`` (N, 3) or (3,) [m] in W (see ``evaluate``)."""
        return self.evaluate(s)[0]

    def tangent(self, s: npt.ArrayLike) -> np.ndarray:
        """Unit tangent ``dp/ds`` (N, 3) or (3,) [-] (see ``evaluate``)."""
        return self.evaluate(s)[1]


class PolylinePath(CartesianPath):
    """Straight segments through vertices, with a sharp corner at each interior vertex.

    Args:
        vertices: Points (K, 3) [m] in W, K >= 2, consecutive points distinct.

    Raises:
        InvalidPath: Wrong shape, non-finite entries or a zero-length segment.
    """

    def __init__(self, vertices: npt.ArrayLike):
        v = np.array(vertices, dtype=float)
        if v.ndim != 2 or v.shape[1] != 3 or v.shape[0] < 2:
            raise InvalidPath(f"vertices must have shape (K, 3) with K >= 2; got {v.shape}")
        if not np.all(np.isfinite(v)):
            raise InvalidPath("vertices must be finite [m]")
        seg = np.diff(v, axis=0)
        lengths = np.linalg.norm(seg, axis=1)
        scale = max(1.0, float(np.max(np.abs(v))))
        short = np.flatnonzero(lengths <= 1e-12 * scale)
        if short.size:
            i = int(short[0])
            raise InvalidPath(
                f"segment {i} from vertex {i} to {i + 1} has length {float(lengths[i])!r} m; remove "
                "repeated vertices"
            )
        v.setflags(write=False)
        self._vertices = v
        self._directions = seg / lengths[:, None]
        self._s = np.concatenate([[0.0], np.cumsum(lengths)])

    @property
    def vertices(self) -> np.ndarray:
        """Vertices (K, 3) [m] (read-only)."""
        return self._vertices

    @property
    def length(self) -> float:
        """Total arc length [m]."""
        return float(self._s[-1])

    @property
    def corners(self) -> tuple[float, ...]:
        """Arc lengths of every vertex [m]; the timing law stops at each.

        It also stops at collinear interior vertices; merge those if it should not.
        """
        return tuple(float(x) for x in self._s)

    def _evaluate(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        i = np.clip(np.searchsorted(self._s, s, side="right") - 1, 0, len(self._directions) - 1)
        d = self._directions[i]
        p = self._vertices[i] + d * (s - self._s[i])[:, None]
        # Snap exact vertex parameters to the stored vertex (no round-off at corners).
        at_vertex = np.isin(s, self._s)
        if np.any(at_vertex):
            p[at_vertex] = self._vertices[np.searchsorted(self._s, s[at_vertex])]
        return p, d.copy(), np.zeros_like(p)


class LinePath(PolylinePath):
    """The straight segment from ``start`` to ``end`` (3,) [m]."""

    def __init__(self, start: npt.ArrayLike, end: npt.ArrayLike):
        super().__init__(np.vstack([_point("start", start), _point("end", end)]))


class CirclePath(CartesianPath):
    """A circular arc about ``center`` in the plane with unit normal ``normal``.

    ``p(s) = c + r (cos(s/r) u + sin(s/r) w)``, with ``u`` the start direction (projected into
    the plane and normalised) and ``w = n x u``; positive sweep turns counter-clockwise about n.

    Args:
        center: Circle centre (3,) [m] in W.
        radius: Radius r [m], > 0.
        normal: Plane normal (3,) [-] (normalised here).
        start_direction: Direction (3,) from the centre to the start point.
        sweep_rad: Swept angle [rad], non-zero (2 pi: a full circle; negative: clockwise).

    Raises:
        InvalidPath: Non-positive radius, zero sweep, a zero normal, or ``start_direction``
            parallel to ``normal``.
    """

    def __init__(
        self,
        center: npt.ArrayLike,
        radius: float,
        normal: npt.ArrayLike = (0.0, 0.0, 1.0),
        start_direction: npt.ArrayLike = (1.0, 0.0, 0.0),
        sweep_rad: float = 2.0 * math.pi,
    ):
        self.center = _point("center", center)
        self.center.setflags(write=False)
        if not (math.isfinite(radius) and radius > 0.0):
            raise InvalidPath(f"radius = {radius!r} m must be finite and > 0")
        if not (math.isfinite(sweep_rad) and sweep_rad != 0.0):
            raise InvalidPath(f"sweep_rad = {sweep_rad!r} rad must be finite and non-zero")
        self.radius = float(radius)
        self.sweep_rad = float(sweep_rad)
        self._n, self._u, self._w = _plane_basis(normal, start_direction)

    @property
    def normal(self) -> np.ndarray:
        """Unit plane normal (3,) [-]."""
        return self._n.copy()

    @property
    def length(self) -> float:
        """Arc length ``r |sweep|`` [m]."""
        return self.radius * abs(self.sweep_rad)

    def _evaluate(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        sign = math.copysign(1.0, self.sweep_rad)
        theta = sign * s / self.radius
        c, sn = np.cos(theta)[:, None], np.sin(theta)[:, None]
        radial = c * self._u + sn * self._w
        p = self.center + self.radius * radial
        t = sign * (-sn * self._u + c * self._w)
        k = -radial / self.radius
        return p, t, k


def square_path(
    center: npt.ArrayLike,
    side_length: float,
    normal: npt.ArrayLike = (0.0, 0.0, 1.0),
    edge_direction: npt.ArrayLike = (1.0, 0.0, 0.0),
) -> PolylinePath:
    """A closed square with sharp corners, traversed counter-clockwise about ``normal``.

    It starts and ends at the corner ``c - (d/2) u - (d/2) w`` and runs first along ``u`` (the
    edge direction projected into the plane), with ``w = n x u`` and d the side length.

    Args:
        center: Square centre (3,) [m] in W.
        side_length: Side length d [m], > 0.
        normal: Plane normal (3,) [-].
        edge_direction: Direction (3,) of the first edge.

    Returns:
        A 5-vertex polyline (the first vertex repeated at the end); its corners are at
        s = 0, d, 2d, 3d, 4d.

    Raises:
        InvalidPath: Non-positive side length, zero normal, or ``edge_direction`` parallel to
            ``normal``.
    """
    c = _point("center", center)
    if not (math.isfinite(side_length) and side_length > 0.0):
        raise InvalidPath(f"side_length = {side_length!r} m must be finite and > 0")
    _, u, w = _plane_basis(normal, edge_direction)
    h = 0.5 * float(side_length)
    corners = [c - h * u - h * w, c + h * u - h * w, c + h * u + h * w, c - h * u + h * w]
    return PolylinePath(np.vstack(corners + [corners[0]]))


# ---------------------------------------------------------------------------------- timing
@dataclass(frozen=True)
class CartesianTrajectory(_UniformGrid):
    """A timed Cartesian point trajectory on a uniform grid (positions in the world frame W).

    Attributes:
        t_s: Sample times (N,) [s], uniform step, starting at 0.
        p: Positions (N, 3) [m].
        v: Velocities (N, 3) [m/s].
        a: Accelerations (N, 3) [m/s^2].
        s: Path parameter (arc length) at each sample (N,) [m], or None if not from a path.
        corner_indices: Sample indices at which the trajectory is at rest on a path corner
            (including the first and last samples when timed by ``time_path``).

    The arrays are read-only.

    Raises:
        InvalidPlanningInput: Shapes that disagree, non-finite samples, or times that are not
            strictly increasing.
    """

    t_s: np.ndarray
    p: np.ndarray
    v: np.ndarray
    a: np.ndarray
    s: np.ndarray | None = None
    corner_indices: tuple[int, ...] = field(default=())

    def __post_init__(self) -> None:
        """Validate shapes and freeze the arrays."""
        t = np.array(self.t_s, dtype=float)
        n = len(t)
        if t.ndim != 1 or n < 1 or (n > 1 and not np.all(np.diff(t) > 0)):
            raise InvalidPlanningInput(
                "CartesianTrajectory.t_s must be a non-empty, strictly increasing 1-D array"
            )
        t.setflags(write=False)
        object.__setattr__(self, "t_s", t)
        for name in ("p", "v", "a"):
            arr = np.array(getattr(self, name), dtype=float)
            if arr.shape != (n, 3):
                raise InvalidPlanningInput(
                    f"CartesianTrajectory.{name} must have shape ({n}, 3); got {arr.shape}"
                )
            if not np.all(np.isfinite(arr)):
                raise InvalidPlanningInput(f"CartesianTrajectory.{name} has non-finite samples")
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        if self.s is not None:
            s = np.array(self.s, dtype=float)
            if s.shape != (n,):
                raise InvalidPlanningInput(
                    f"CartesianTrajectory.s must have shape ({n},); got {s.shape}"
                )
            s.setflags(write=False)
            object.__setattr__(self, "s", s)
        object.__setattr__(self, "corner_indices", tuple(int(i) for i in self.corner_indices))

    @property
    def speed(self) -> np.ndarray:
        """Path speed ``|v|`` (N,) [m/s]."""
        return np.linalg.norm(self.v, axis=1)


def time_path(path: CartesianPath, limits: PathLimits, dt_s: float) -> CartesianTrajectory:
    """Time a path with a jerk-limited, rest-to-rest ruckig law on s between corners.

    Each smooth section between consecutive ``path.corners`` is timed on its own, from rest to
    rest, and rounded up to whole control periods; the sections are joined on one uniform grid.
    Corner samples are exact: ``s`` equals the corner's arc length and ``v`` is zero there.

    Args:
        path: The geometric path.
        limits: Speed, tangential acceleration and jerk limits on s.
        dt_s: Control period [s].

    Returns:
        The sampled trajectory, with ``s`` and ``corner_indices`` filled in.

    Raises:
        InvalidPlanningInput: Bad ``dt_s``.
        TrajectoryGenerationFailed: Ruckig failed on a section.
    """
    dt = check_time("dt_s", dt_s)
    corners = path.corners
    joint_limits = limits.as_joint_limits()
    sections = [
        plan_ruckig([s0], [s1], joint_limits, dt, ("s",))
        for s0, s1 in zip(corners[:-1], corners[1:], strict=True)
    ]
    # concatenate keeps each shared corner sample once, so corner k follows the steps of
    # sections 0..k-1.
    corner_indices = np.cumsum([0] + [len(sec.t_s) - 1 for sec in sections])
    law = concatenate(sections)
    s, sd, sdd = law.q[:, 0], law.v[:, 0], law.a[:, 0]
    p, tangent, curvature = path.evaluate(s)
    v = tangent * sd[:, None]
    a = tangent * sdd[:, None] + curvature * (sd * sd)[:, None]
    return CartesianTrajectory(law.t_s, p, v, a, s=s, corner_indices=tuple(corner_indices))


# ---------------------------------------------------------------------------------- joints
def to_joint_trajectory(
    cart_traj: CartesianTrajectory,
    ik: Callable[[np.ndarray], npt.ArrayLike],
    jacobian: Callable[[np.ndarray], npt.ArrayLike],
    names: Sequence[str],
    jacobian_dot: Callable[[np.ndarray, np.ndarray], npt.ArrayLike] | None = None,
    max_joint_step_rad: float = 0.5,
    task_dims: int | None = None,
    unwrap: bool = False,
) -> JointTrajectory:
    """Joint trajectory that moves a point along a Cartesian trajectory.

    With ``J`` the (m, n) position Jacobian returned by ``jacobian`` (m = 2 uses the x-y
    components of the Cartesian samples, m = 3 uses x-y-z):

        q = ik(p[:m]),   qd = J^+ v[:m],   qdd = J^+ (a[:m] - Jdot qd).

    For a redundant arm (n > m) ``qd`` and ``qdd`` are the minimum-norm solutions; they are the
    time derivatives of ``q`` only if the IK resolves the redundancy the same way. The tests
    cover the non-redundant case (2-link arm, identity "robot").

    Args:
        cart_traj: The Cartesian trajectory (world frame W).
        ik: Maps a target (m,) [m] (the first m components of p) to joint positions (n,)
            [rad]; it should pick one consistent branch (a branch switch is rejected, see
            ``max_joint_step_rad``). Its exceptions are wrapped with the sample time.
        jacobian: Maps q (n,) [rad] to the position Jacobian (m, n) [m/rad] in W.
        names: Joint names of the n columns.
        jacobian_dot: Optional map ``(q, qd) -> Jdot`` (m, n) [m/(rad s)]. If None, ``Jdot qd``
            is a central finite difference of J along qd (step ``FD_JOINT_STEP`` rad).
        max_joint_step_rad: Largest joint change between consecutive samples [rad] before the
            IK is considered to have jumped branches.
        task_dims: m, the number of Cartesian components used (2: x-y, 3: x-y-z). If None, it
            is the row count of ``jacobian(zeros(n))`` (one probe call at q = 0).
        unwrap: If True, every joint is revolute and each IK solution is shifted by whole turns
            (2 pi) to the one nearest the previous sample, so an IK that wraps angles into
            (-pi, pi] gives a continuous trajectory (check the result against joint limits).

    Returns:
        A JointTrajectory on the same time grid.

    Raises:
        PathIKFailed: The IK raised at a sample (time, index and target in the message; the
            IK's exception is the ``__cause__``).
        PathNotTrackable: ``J qd != v`` or ``J qdd + Jdot qd != a`` beyond round-off at a sample
            (a singular Jacobian with motion along its null direction).
        InvalidPath: The trajectory moves along an axis the m-row Jacobian ignores.
        InvalidPlanningInput: Bad names, a Jacobian or IK output of the wrong shape, non-finite
            outputs, or an IK branch jump.
    """
    names = check_names(names)
    n = len(names)
    if not (math.isfinite(max_joint_step_rad) and max_joint_step_rad > 0.0):
        raise InvalidPlanningInput(
            f"max_joint_step_rad must be finite and > 0 [rad]; got {max_joint_step_rad!r}"
        )
    if task_dims is None:
        J_probe = np.asarray(jacobian(np.zeros(n)), dtype=float)
        m = J_probe.shape[0] if J_probe.ndim == 2 else -1
    else:
        m = int(task_dims)
    if m not in (1, 2, 3):
        raise InvalidPlanningInput(
            f"task dimension must be 1, 2 or 3 (rows of the Jacobian); got {m} "
            f"(task_dims={task_dims!r})"
        )
    _check_ignored_axes(cart_traj, m)
    n_samples = len(cart_traj.t_s)
    q = np.empty((n_samples, n))
    qd = np.empty_like(q)
    qdd = np.empty_like(q)
    for i in range(n_samples):
        t_i = float(cart_traj.t_s[i])
        target = cart_traj.p[i, :m].copy()
        try:
            q_i = np.asarray(ik(target), dtype=float)
        except Exception as exc:  # any IK failure is re-raised with the sample time
            raise PathIKFailed(t_i, i, target, exc) from exc
        if q_i.shape != (n,) or not np.all(np.isfinite(q_i)):
            raise InvalidPlanningInput(
                f"ik returned {q_i!r} at t = {t_i:.6g} s; expected {n} finite joint positions"
            )
        if unwrap and i > 0:
            q_i = q_i + 2.0 * math.pi * np.round((q[i - 1] - q_i) / (2.0 * math.pi))
        J = np.asarray(jacobian(q_i), dtype=float)
        if J.shape != (m, n):
            raise InvalidPlanningInput(
                f"jacobian returned shape {J.shape} at t = {t_i:.6g} s; expected ({m}, {n})"
            )
        if i > 0:
            jump = np.abs(q_i - q[i - 1])
            j = int(np.argmax(jump))
            if jump[j] > max_joint_step_rad:
                raise InvalidPlanningInput(
                    f"ik jumped {jump[j]:.3g} rad on joint {names[j]!r} between t = "
                    f"{float(cart_traj.t_s[i - 1]):.6g} s and {t_i:.6g} s (limit "
                    f"max_joint_step_rad = {max_joint_step_rad:g} rad); the IK switched branch "
                    "or the path passes through a singularity"
                )
        J_pinv = np.linalg.pinv(J)
        qd_i = J_pinv @ cart_traj.v[i, :m]
        if jacobian_dot is not None:
            Jdot_qd = np.asarray(jacobian_dot(q_i, qd_i), dtype=float) @ qd_i
        else:
            # No analytic Jdot: central finite difference of J along qd,
            # Jdot qd = (dJ/dq . qd) qd ~ (J(q + h qd) - J(q - h qd)) / (2 h) qd, with h [s] chosen
            # so that the joint displacement h |qd| is FD_JOINT_STEP rad (error O(h^2)).
            speed = float(np.linalg.norm(qd_i))
            if speed > 0.0:
                h = FD_JOINT_STEP / speed
                J_plus = np.asarray(jacobian(q_i + h * qd_i), dtype=float)
                J_minus = np.asarray(jacobian(q_i - h * qd_i), dtype=float)
                Jdot_qd = (J_plus - J_minus) @ qd_i / (2.0 * h)
            else:
                Jdot_qd = np.zeros(m)
        qdd_i = J_pinv @ (cart_traj.a[i, :m] - Jdot_qd)
        for label, unit, got, want in (
            ("velocity", "m/s", J @ qd_i, cart_traj.v[i, :m]),
            ("acceleration", "m/s^2", J @ qdd_i + Jdot_qd, cart_traj.a[i, :m]),
        ):
            residual = float(np.linalg.norm(got - want))
            if residual > TRACKING_RTOL * max(1.0, float(np.linalg.norm(want))):
                raise PathNotTrackable(
                    f"at t = {t_i:.6g} s (sample {i}) the joints cannot produce the Cartesian "
                    f"{label} {want.tolist()} {unit}: residual {residual:.3g} {unit} with "
                    f"Jacobian singular values {np.linalg.svd(J, compute_uv=False).tolist()}. "
                    "Keep the path away from singular configurations (e.g. the workspace "
                    "boundary) or slow it to rest there.",
                    t_i,
                    i,
                    residual,
                )
        q[i] = q_i
        qd[i] = qd_i
        qdd[i] = qdd_i
    return JointTrajectory(cart_traj.t_s.copy(), q, qd, qdd, names)


# ---------------------------------------------------------------------------------- helpers
def _check_ignored_axes(cart_traj: CartesianTrajectory, m: int) -> None:
    if m >= 3:
        return
    drift = np.abs(cart_traj.p[:, m:] - cart_traj.p[0, m:])
    moving = max(float(np.max(drift)), float(np.max(np.abs(cart_traj.v[:, m:]))))
    if moving > IGNORED_AXIS_ATOL:
        axis = "xyz"[m:]
        raise InvalidPath(
            f"the trajectory moves {moving:.3g} (m or m/s) along {axis}, which the {m}-row "
            "Jacobian ignores; plan the path in the arm's plane (constant "
            f"{axis}) or pass a 3-row Jacobian"
        )


def _point(label: str, value: npt.ArrayLike) -> np.ndarray:
    arr = np.array(value, dtype=float)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise InvalidPath(f"{label} must be a finite 3-D point [m]; got {value!r}")
    return arr


def _plane_basis(
    normal: npt.ArrayLike, start_direction: npt.ArrayLike
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    n = np.array(normal, dtype=float)
    d = np.array(start_direction, dtype=float)
    if n.shape != (3,) or not np.all(np.isfinite(n)) or np.linalg.norm(n) < 1e-12:
        raise InvalidPath(f"normal must be a finite non-zero 3-vector; got {normal!r}")
    if d.shape != (3,) or not np.all(np.isfinite(d)):
        raise InvalidPath(f"start direction must be a finite 3-vector; got {start_direction!r}")
    n = n / np.linalg.norm(n)
    u = d - (d @ n) * n
    if np.linalg.norm(u) < 1e-9 * max(1.0, float(np.linalg.norm(d))):
        raise InvalidPath(
            f"start direction {d.tolist()} is parallel to the normal {n.tolist()}; give a "
            "direction in the plane"
        )
    u = u / np.linalg.norm(u)
    w = np.cross(n, u)
    for arr in (n, u, w):
        arr.setflags(write=False)
    return n, u, w
