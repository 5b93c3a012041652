"""Analytic kinematics and inverse kinematics of the planar 2-link arm.

Notation (Drake monograms): W is the world frame (the arm's plane is W's x-y plane), S the
end-effector site. ``p_WS`` is the site position in W, restricted to (x, y). Joint angles
``q = (q1, q2)`` [rad] are the shoulder and elbow hinge angles about +z.

Forward kinematics, with ``l1`` the shoulder-to-elbow length and ``l2`` the elbow-to-site length
(on the mbctl arm ``l2`` is link 2 plus the 0.015 m site offset, 0.315 m)::

    p_WS = p_WO + [l1 cos q1 + l2 cos(q1 + q2),  l1 sin q1 + l2 sin(q1 + q2)]

    J(q) = d p_WS / d q = [[-l1 s1 - l2 s12, -l2 s12],
                           [ l1 c1 + l2 c12,  l2 c12]],   det J = l1 l2 sin q2

The reachable set is the annulus ``|l1 - l2| <= |p_WS - p_WO| <= l1 + l2``. The arm is singular
where ``sin q2 = 0`` (stretched out or folded back); there the pseudo-inverse step blows up and
damped least squares stays bounded by ``|e| / (2 lambda)``.

The geometry is read from the Robot (Pinocchio joint placements and the site frame placement),
never hard-coded.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from mbctl.control.exceptions import IKSetupError, KinematicsError, UnreachableTarget
from mbctl.control.ik.loop import IKResult, iterate
from mbctl.control.tasks.residuals import TaskResidual, Tolerance
from mbctl.robots.model_pair import Robot

#: Relative tolerance [-] on the workspace radius within which a target on the boundary is
#: treated as reachable (round-off in ``hypot`` and the law of cosines).
BOUNDARY_RTOL = 1e-12

#: Tolerance [m] on the off-axis components of the link vectors for the geometry to count as
#: a planar arm with links along each joint frame's x axis.
PLANARITY_ATOL = 1e-12


class ElbowBranch(enum.Enum):
    """Which of the two analytic IK solutions.

    ``UP`` has ``q2 <= 0`` and ``DOWN`` has ``q2 >= 0``. For a target on the +x axis the UP
    elbow lies at positive y (above the shoulder-target line).
    """

    UP = "up"
    DOWN = "down"


class Workspace(NamedTuple):
    """Reachable annulus of the site, centred on the shoulder axis.

    Attributes:
        r_min: Inner radius ``|l1 - l2|`` [m].
        r_max: Outer radius ``l1 + l2`` [m].
        center: Shoulder axis position (2,) [m] in the world x-y plane.
    """

    r_min: float
    r_max: float
    center: np.ndarray


@dataclass(frozen=True)
class TwoLinkArm:
    """Geometry and analytic kinematics of a planar 2R arm.

    e(q) for IK is ``p_target - p_WS(q)``; J(q) is the 2x2 position Jacobian above.

    Attributes:
        link1_length: Shoulder axis to elbow axis [m].
        link2_length: Elbow axis to the end-effector site [m].
        base_x: Shoulder axis x position in the world [m].
        base_y: Shoulder axis y position in the world [m].
        site: Name of the end-effector site (a Pinocchio frame and a MuJoCo site).
    """

    link1_length: float
    link2_length: float
    base_x: float = 0.0
    base_y: float = 0.0
    site: str = "end_effector"

    def __post_init__(self) -> None:
        """Validate the lengths."""
        for name in ("link1_length", "link2_length"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise KinematicsError(f"{name} must be a positive finite length [m]; got {value!r}")

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_robot(cls, robot: Robot, site: str = "end_effector") -> TwoLinkArm:
        """Read the geometry from a Robot's Pinocchio model.

        Args:
            robot: A robot with exactly two revolute-z joints in series and the site ``site``.
            site: End-effector site name.

        Raises:
            KinematicsError: The model is not a planar 2R arm with links along x.
            UnknownNameError: No frame called ``site``.
        """
        model = robot.pin_model
        frame_id = robot.frame_id(site)
        kinds = [model.joints[i].shortname() for i in range(1, model.njoints)]
        if kinds != ["JointModelRZ", "JointModelRZ"]:
            raise KinematicsError(
                f"{robot.name!r} has joints {kinds}; a planar 2-link arm needs two revolute-z "
                "joints (JointModelRZ, JointModelRZ)."
            )
        frame = model.frames[frame_id]
        if frame.parentJoint != 2:
            raise KinematicsError(
                f"Site {site!r} hangs on joint {model.names[frame.parentJoint]!r}; expected the "
                f"second joint {model.names[2]!r}."
            )
        X_base = model.jointPlacements[1]
        X_elbow = model.jointPlacements[2]
        p_site = frame.placement.translation
        for label, placement_rot in (("shoulder", X_base.rotation), ("elbow", X_elbow.rotation)):
            if not np.allclose(placement_rot, np.eye(3), atol=PLANARITY_ATOL, rtol=0.0):
                raise KinematicsError(f"{label} joint placement is rotated; expected identity.")
        for label, vec in (("elbow placement", X_elbow.translation), ("site placement", p_site)):
            if abs(vec[1]) > PLANARITY_ATOL or abs(vec[2]) > PLANARITY_ATOL:
                raise KinematicsError(
                    f"{label} {vec.tolist()} m is not along the joint frame's x axis; the analytic "
                    "module expects links along x."
                )
        return cls(
            link1_length=float(X_elbow.translation[0]),
            link2_length=float(p_site[0]),
            base_x=float(X_base.translation[0]),
            base_y=float(X_base.translation[1]),
            site=site,
        )

    # ------------------------------------------------------------------ workspace
    @property
    def base(self) -> np.ndarray:
        """Shoulder axis position (2,) [m] in the world x-y plane."""
        return np.array([self.base_x, self.base_y])

    @property
    def r_min(self) -> float:
        """Inner workspace radius ``|l1 - l2|`` [m]."""
        return abs(self.link1_length - self.link2_length)

    @property
    def r_max(self) -> float:
        """Outer workspace radius ``l1 + l2`` [m]."""
        return self.link1_length + self.link2_length

    def workspace(self) -> Workspace:
        """The reachable annulus."""
        return Workspace(self.r_min, self.r_max, self.base)

    def is_reachable(self, target: npt.ArrayLike) -> bool:
        """Whether ``target`` (2,) [m] (world x, y) lies in the reachable annulus."""
        r = float(np.hypot(*(_target2(target) - self.base)))
        tol = BOUNDARY_RTOL * self.r_max
        return self.r_min - tol <= r <= self.r_max + tol

    # ------------------------------------------------------------------ kinematics
    def forward_kinematics(self, q: npt.ArrayLike) -> np.ndarray:
        """Site position ``p_WS`` (2,) [m] (world x, y) at joint angles ``q`` (2,) [rad]."""
        q1, q2 = _q2(q)
        l1, l2 = self.link1_length, self.link2_length
        return np.array(
            [
                self.base_x + l1 * math.cos(q1) + l2 * math.cos(q1 + q2),
                self.base_y + l1 * math.sin(q1) + l2 * math.sin(q1 + q2),
            ]
        )

    def elbow_position(self, q: npt.ArrayLike) -> np.ndarray:
        """Elbow axis position (2,) [m] (world x, y) at ``q`` (2,) [rad]."""
        q1, _ = _q2(q)
        return self.base + self.link1_length * np.array([math.cos(q1), math.sin(q1)])

    def jacobian(self, q: npt.ArrayLike) -> np.ndarray:
        """Position Jacobian ``d p_WS / d q`` (2, 2) [m/rad], world x-y rows."""
        q1, q2 = _q2(q)
        l1, l2 = self.link1_length, self.link2_length
        s1, c1 = math.sin(q1), math.cos(q1)
        s12, c12 = math.sin(q1 + q2), math.cos(q1 + q2)
        return np.array([[-l1 * s1 - l2 * s12, -l2 * s12], [l1 * c1 + l2 * c12, l2 * c12]])

    def manipulability(self, q: npt.ArrayLike) -> float:
        """Yoshikawa manipulability ``sqrt(det(J J^T)) = l1 l2 |sin q2|`` [m^2]."""
        _, q2 = _q2(q)
        return self.link1_length * self.link2_length * abs(math.sin(q2))

    def is_singular(self, q: npt.ArrayLike, tol: float = 1e-6) -> bool:
        """Whether ``q`` is within ``tol`` of a singularity: ``|sin q2| < tol`` [-]."""
        _, q2 = _q2(q)
        return abs(math.sin(q2)) < tol

    # ------------------------------------------------------------------ analytic IK
    def inverse_kinematics(
        self, target: npt.ArrayLike, branch: ElbowBranch = ElbowBranch.UP
    ) -> np.ndarray:
        """Joint angles (2,) [rad] placing the site at ``target`` (2,) [m] (world x, y).

        Angles are in (-pi, pi]. At the workspace boundary both branches coincide.

        Raises:
            UnreachableTarget: ``target`` is outside the annulus r_min..r_max (message states both).
        """
        p = _target2(target)
        d = p - self.base
        r = float(np.hypot(d[0], d[1]))
        tol = BOUNDARY_RTOL * self.r_max
        if not (self.r_min - tol <= r <= self.r_max + tol):
            raise UnreachableTarget(p, r, self.r_min, self.r_max)
        l1, l2 = self.link1_length, self.link2_length
        c2 = (r * r - l1 * l1 - l2 * l2) / (2.0 * l1 * l2)
        c2 = min(1.0, max(-1.0, c2))
        q2 = math.acos(c2)
        if branch is ElbowBranch.UP:
            q2 = -q2
        q1 = math.atan2(d[1], d[0]) - math.atan2(l2 * math.sin(q2), l1 + l2 * math.cos(q2))
        q1 = math.atan2(math.sin(q1), math.cos(q1))
        return np.array([q1, q2])

    def inverse_kinematics_both(self, target: npt.ArrayLike) -> dict[ElbowBranch, np.ndarray]:
        """Both analytic IK solutions, by branch (see ``inverse_kinematics``).

        Raises:
            UnreachableTarget: ``target`` is outside the annulus r_min..r_max.
        """
        return {b: self.inverse_kinematics(target, b) for b in ElbowBranch}


# ---------------------------------------------------------------------- iterative IK
def pinv_ik(
    arm: TwoLinkArm,
    target: npt.ArrayLike,
    q0: npt.ArrayLike,
    tol: float = 1e-10,
    max_iters: int = 100,
    max_task_step: float | None = None,
) -> IKResult:
    """Newton-Raphson IK with the Moore-Penrose pseudo-inverse: ``dq = J^+ e``.

    Unbounded near singularities (the step grows like ``1 / sin q2``).

    Args:
        arm: Arm geometry.
        target: Site target (2,) [m] (world x, y).
        q0: Initial joint angles (2,) [rad].
        tol: Convergence tolerance on the position error norm [m].
        max_iters: Maximum number of steps.
        max_task_step: If given, the error is clamped to this norm [m] before each step.

    Raises:
        IKSetupError: Non-positive ``tol``, ``max_iters`` or ``max_task_step``.
    """
    return _iterate(arm, target, q0, tol, max_iters, 0.0, max_task_step)


def dls_ik(
    arm: TwoLinkArm,
    target: npt.ArrayLike,
    q0: npt.ArrayLike,
    damping: float = 0.05,
    tol: float = 1e-10,
    max_iters: int = 200,
    max_task_step: float | None = 0.05,
) -> IKResult:
    """Damped least-squares IK: ``dq = J^T (J J^T + lambda^2 I)^-1 e``.

    The step is bounded, ``|dq| <= min(|e|, max_task_step) / (2 lambda)``, also at singularities;
    for an unreachable target it converges to the closest reachable point (``converged`` False,
    residual reported). Clamping the error (Buss) keeps large errors from making the
    linearisation overshoot.

    Args:
        arm: Arm geometry.
        target: Site target (2,) [m] (world x, y).
        q0: Initial joint angles (2,) [rad].
        damping: Damping ``lambda`` [m] (> 0).
        tol: Convergence tolerance on the position error norm [m].
        max_iters: Maximum number of steps.
        max_task_step: Error clamp [m] applied before each step; None disables it.

    Raises:
        IKSetupError: Non-positive ``damping``, ``tol``, ``max_iters`` or ``max_task_step``.
    """
    if not (math.isfinite(damping) and damping > 0.0):
        raise IKSetupError(f"damping must be a positive finite value [m]; got {damping!r}")
    return _iterate(arm, target, q0, tol, max_iters, damping, max_task_step)


class _TwoLinkStepper:
    """Pseudo-inverse or damped least-squares steps on the arm: an :class:`IKStepper`."""

    def __init__(self, arm: TwoLinkArm, target: np.ndarray, damping: float, max_task_step: float | None):
        self.arm, self.target, self.damping, self.max_task_step = arm, target, damping, max_task_step
        self._q = np.zeros(2)

    @property
    def q(self) -> np.ndarray:
        return self._q.copy()

    def update(self, q: npt.ArrayLike) -> None:
        self._q = _q2(q).copy()

    def task_residuals(self) -> dict[str, TaskResidual]:
        error = float(np.linalg.norm(self.target - self.arm.forward_kinematics(self._q)))
        return {self.arm.site: TaskResidual(position_m=error)}

    @property
    def levels(self) -> tuple[tuple[str, ...], ...]:
        return ((self.arm.site,),)

    def advance(self) -> float:
        e = self.target - self.arm.forward_kinematics(self._q)
        norm = float(np.linalg.norm(e))
        if self.max_task_step is not None and norm > self.max_task_step:
            e = e * (self.max_task_step / norm)
        J = self.arm.jacobian(self._q)
        if self.damping > 0.0:
            dq = J.T @ np.linalg.solve(J @ J.T + self.damping**2 * np.eye(2), e)
        else:
            dq = np.linalg.pinv(J) @ e
        self._q = self._q + dq
        return float(np.max(np.abs(dq)))


def _iterate(
    arm: TwoLinkArm,
    target: npt.ArrayLike,
    q0: npt.ArrayLike,
    tol: float,
    max_iters: int,
    damping: float,
    max_task_step: float | None,
) -> IKResult:
    if max_task_step is not None and not (math.isfinite(max_task_step) and max_task_step > 0.0):
        raise IKSetupError(
            f"max_task_step must be a positive finite length [m] or None; got {max_task_step!r}"
        )
    if not (math.isfinite(tol) and tol > 0.0):
        raise IKSetupError(f"tol must be a positive finite error norm [m]; got {tol!r}")
    stepper = _TwoLinkStepper(arm, _target2(target), damping, max_task_step)
    # step_tol 0: iterate to the cap (DLS creeps to the closest point of an unreachable target)
    return iterate(stepper, q0, Tolerance(position_m=tol), max_iters, step_tol=0.0)


# ---------------------------------------------------------------------- helpers
def _q2(q: npt.ArrayLike) -> np.ndarray:
    arr = np.asarray(q, dtype=float)
    if arr.shape != (2,) or not np.all(np.isfinite(arr)):
        raise IKSetupError(f"q must be 2 finite joint angles [rad]; got {q!r}")
    return arr


def _target2(target: npt.ArrayLike) -> np.ndarray:
    arr = np.asarray(target, dtype=float)
    if arr.shape == (3,):
        arr = arr[:2]
    if arr.shape != (2,) or not np.all(np.isfinite(arr)):
        raise IKSetupError(
            f"target must be a finite (x, y) or (x, y, z) position [m]; got {target!r}"
        )
    return arr
