"""A jerk-limited timing law for Cartesian paths, and the conversion of a timed path to joints.

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
from mbctl.planners.paths import CartesianPath
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
