"""Acceleration-level tasks for whole-body inverse dynamics, on the differential-IK tasks.

One task object serves velocity IK and inverse dynamics: each class here wraps a task of
:mod:`mbctl.control.ik.tasks` (which owns the target and the error ``e(q)``) and adds what the
acceleration level needs: the motion Jacobian ``J`` (k, nv), the drift ``Jdot v`` (k,) and the
desired acceleration from a PD law on the IK task's error::

    J vdot + Jdot v = a_des,   a_des = a_ref + kp (-e) + kd (v_ref - J v)

so that the QP minimises ``weight^2 |J vdot - (a_des - Jdot v)|^2``. Gains come from a natural
frequency and a damping ratio (``kp = omega^2``, ``kd = 2 zeta omega``: the loop is already
normalised by M(q)).

For frame poses and orientations ``J`` is the frame Jacobian J_F (LOCAL frame F, the TSID
convention) rather than the log-map Jacobian of the IK error: the two agree at the target, and
``J_F`` has an exact drift (the frame's acceleration at zero vdot: spatial in LOCAL, classical
in world-aligned axes), which the tests check against finite differences.

Notation (Drake monograms): W world, F a task frame, C the centre of mass.
"""

from __future__ import annotations

import abc
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from mbctl.control.exceptions import WBCSetupError
from mbctl.control.ik.state import IKState
from mbctl.control.ik.tasks import (
    ComTask,
    FrameOrientationTask,
    FramePoseTask,
    FramePositionTask,
    PostureTask,
)


@dataclass(frozen=True)
class TaskGains:
    """Weight and PD gains of an acceleration task.

    Attributes:
        weight: Cost weight [cost]/[task acceleration unit] (> 0; squared in the QP).
        omega_rad_s: Closed-loop natural frequency [rad/s] (>= 0).
        zeta: Damping ratio [-] (>= 0).
    """

    weight: float
    omega_rad_s: float = 10.0
    zeta: float = 1.0

    def __post_init__(self) -> None:
        for name in ("weight", "omega_rad_s", "zeta"):
            value = getattr(self, name)
            if not np.isfinite(value) or value < 0 or (name == "weight" and value == 0):
                raise WBCSetupError(f"TaskGains.{name} must be finite and "
                                    f"{'> 0' if name == 'weight' else '>= 0'}; got {value!r}")

    @property
    def kp(self) -> float:
        """Stiffness ``omega^2`` [1/s^2]."""
        return self.omega_rad_s**2

    @property
    def kd(self) -> float:
        """Damping ``2 zeta omega`` [1/s]."""
        return 2.0 * self.zeta * self.omega_rad_s


class DynamicsState(IKState):
    """``(q, v)`` with every term inverse dynamics needs, from one set of Pinocchio passes.

    ``update(q, v)`` runs ``pin.computeAllTerms`` (M, nle = b, joint Jacobians, CoM and its
    Jacobian, and the body accelerations at zero vdot, i.e. the drifts), frame placements, and
    the centroidal map and its time variation (``Ag``, ``dAg``). IK tasks read the same data.

    Attributes:
        v: Velocity (nv,), Pinocchio convention (base twist in the base frame).
        mass: Total mass [kg].
    """

    def __init__(self, model: pin.Model, q: npt.ArrayLike | None = None, v: npt.ArrayLike | None = None):
        self.v = np.zeros(model.nv)
        self._lower = np.tril_indices(model.nv, -1)
        self._M: np.ndarray | None = None
        self.mass = float(sum(inertia.mass for inertia in model.inertias))
        super().__init__(model, q, with_com=True)
        if v is not None:
            self.update(self.q, v)

    def update(self, q: npt.ArrayLike, v: npt.ArrayLike | None = None) -> None:  # type: ignore[override]
        """Set ``q`` (nq,) and ``v`` (nv,) (default: zero) and recompute every term."""
        self._q[:] = q
        if v is None:
            self.v[:] = 0.0
        else:
            self.v[:] = v
        model, data = self.model, self.data
        pin.computeAllTerms(model, data, self._q, self.v)
        pin.updateFramePlacements(model, data)
        self._drift_com = None
        self._M = None
        pin.computeCentroidalMapTimeVariation(model, data, self._q, self.v)

    @property
    def M(self) -> np.ndarray:  # noqa: N802 - the mass matrix is M in every text
        """Joint-space inertia (nv, nv) at q, both triangles filled (read-only, once per update)."""
        if self._M is None:  # Pinocchio fills the upper triangle only
            M = self.data.M.copy()
            M[self._lower] = M.T[self._lower]
            M.setflags(write=False)
            self._M = M
        return self._M

    @property
    def b(self) -> np.ndarray:
        """Bias forces (nv,) [N m]: Coriolis, centrifugal and gravity, C(q, v) v + g(q)."""
        return self.data.nle

    def com_drift(self) -> np.ndarray:
        """``Jdot_com v`` (3,) [m/s^2]: the CoM acceleration at zero vdot."""
        return (self.data.dAg[:3] @ self.v) / self.mass

    def frame_jacobian(self, frame_id: int, reference: pin.ReferenceFrame) -> np.ndarray:
        """``J_F`` (6, nv) of frame ``frame_id`` in ``reference`` ([v; w])."""
        return pin.getFrameJacobian(self.model, self.data, frame_id, reference).reshape(6, -1)  # nv = 1

    def frame_drift(self, frame_id: int, reference: pin.ReferenceFrame) -> np.ndarray:
        """``d/dt(J_F) v`` (6,) in ``reference``: the frame's acceleration at zero vdot.

        In LOCAL, the derivative of the body twist is the spatial acceleration; in
        LOCAL_WORLD_ALIGNED (and WORLD-aligned linear rows) it is the classical acceleration of
        the frame origin.
        """
        if reference == pin.LOCAL:
            return pin.getFrameAcceleration(self.model, self.data, frame_id, reference).vector
        return pin.getFrameClassicalAcceleration(self.model, self.data, frame_id, reference).vector

    def frame_velocity(self, frame_id: int, reference: pin.ReferenceFrame) -> np.ndarray:
        """The frame's twist (6,) [m/s, rad/s] in ``reference``."""
        return pin.getFrameVelocity(self.model, self.data, frame_id, reference).vector


class AccelerationTask(abc.ABC):
    """Base class: ``rows(state) -> (J, rhs)``, the least-squares rows ``J vdot ≈ rhs``.

    Attributes:
        name: Report label.
        gains: Weight and PD gains.
        k: Task dimension.
    """

    name: str
    k: int

    def __init__(self, name: str, k: int, gains: TaskGains):
        self.name, self.k, self.gains = name, k, gains

    @abc.abstractmethod
    def rows(self, state: DynamicsState) -> tuple[np.ndarray, np.ndarray]:
        """``(J (k, nv), a_des - Jdot v (k,))`` at ``state``."""

    @abc.abstractmethod
    def jacobian_and_drift(self, state: DynamicsState) -> tuple[np.ndarray, np.ndarray]:
        """``(J (k, nv), Jdot v (k,))`` at ``state`` (tested against finite differences)."""


class _PointAcceleration(AccelerationTask):
    """A point in W (CoM, frame origin): ``e = p - p_ref`` from the IK task, world-frame references."""

    ik: ComTask | FramePositionTask

    def _init_references(self) -> None:
        self.v_ref = np.zeros(3)
        self.a_ref = np.zeros(3)

    def set_reference(self, p: npt.ArrayLike, v: npt.ArrayLike = (0, 0, 0),
                      a: npt.ArrayLike = (0, 0, 0)) -> None:
        """Desired position (3,) [m], velocity [m/s] and acceleration [m/s^2] in W."""
        self.ik.set_target(p)
        self.v_ref[:] = v
        self.a_ref[:] = a

    def rows(self, state: DynamicsState) -> tuple[np.ndarray, np.ndarray]:
        """``a_des = a_ref - kp e + kd (v_ref - J v)`` rows."""
        J, drift = self.jacobian_and_drift(state)
        g = self.gains
        a_des = self.a_ref - g.kp * self.ik.compute_error(state) + g.kd * (self.v_ref - J @ state.v)
        return J, a_des - drift


class ComAcceleration(_PointAcceleration):
    """Centre of mass (world frame): ``J = J_com``, ``e = p_WC - p_ref`` (from :class:`ComTask`)."""

    def __init__(self, gains: TaskGains, name: str = "com"):
        super().__init__(name, 3, gains)
        self.ik = self._com = ComTask(name=name)
        self._init_references()

    @property
    def p_ref(self) -> np.ndarray:
        """The desired CoM position (3,) [m] in W (a copy).

        Raises:
            IKSetupError: No reference set yet.
        """
        return self._com.target

    def jacobian_and_drift(self, state: DynamicsState) -> tuple[np.ndarray, np.ndarray]:
        """``(J_com, Jdot_com v)``."""
        return state.com_jacobian(), state.com_drift()


class FrameOrientationAcceleration(AccelerationTask):
    """Orientation of a frame F: ``J = J_F[3:]`` (LOCAL), error ``log3(R_FT)`` from the IK task."""

    def __init__(self, frame: str, model: pin.Model, gains: TaskGains, name: str | None = None):
        self.ik = FrameOrientationTask(frame, model, name=name)
        super().__init__(self.ik.name, 3, gains)
        self.fid = self.ik.frame_id

    def set_reference(self, transform_target_to_world: pin.SE3) -> None:
        """Desired pose ``X_WT`` (its rotation is used); zero angular velocity and acceleration."""
        self.ik.set_target(transform_target_to_world)

    def jacobian_and_drift(self, state: DynamicsState) -> tuple[np.ndarray, np.ndarray]:
        """``(J_F[3:], (Jdot_F v)[3:])`` in F."""
        return state.frame_jacobian(self.fid, pin.LOCAL)[3:], state.frame_drift(self.fid, pin.LOCAL)[3:]

    def rows(self, state: DynamicsState) -> tuple[np.ndarray, np.ndarray]:
        """Orientation rows."""
        J, drift = self.jacobian_and_drift(state)
        g = self.gains
        a_des = g.kp * self.ik.compute_error(state) - g.kd * (J @ state.v)
        return J, a_des - drift


class FramePoseAcceleration(AccelerationTask):
    """Pose of a frame F (swing foot): ``J = J_F`` (LOCAL), error ``log6(X_FT)`` from the IK task.

    References in the world frame (``v_ref``, ``a_ref`` linear (3,) [m/s, m/s^2]); the angular
    reference is zero velocity and acceleration.
    """

    def __init__(self, frame: str, model: pin.Model, gains: TaskGains, name: str | None = None):
        self.ik = FramePoseTask(frame, model, name=name)
        super().__init__(self.ik.name, 6, gains)
        self.fid = self.ik.frame_id
        self.v_ref_W = np.zeros(3)
        self.a_ref_W = np.zeros(3)

    def set_reference(self, transform_target_to_world: pin.SE3, v: npt.ArrayLike = (0, 0, 0),
                      a: npt.ArrayLike = (0, 0, 0)) -> None:
        """Desired pose ``X_WT``, linear velocity [m/s] and acceleration [m/s^2] in W."""
        self.ik.set_target(transform_target_to_world)
        self.v_ref_W[:] = v
        self.a_ref_W[:] = a

    def jacobian_and_drift(self, state: DynamicsState) -> tuple[np.ndarray, np.ndarray]:
        """``(J_F, Jdot_F v)`` in F."""
        return state.frame_jacobian(self.fid, pin.LOCAL), state.frame_drift(self.fid, pin.LOCAL)

    def rows(self, state: DynamicsState) -> tuple[np.ndarray, np.ndarray]:
        """Pose rows."""
        J, drift = self.jacobian_and_drift(state)
        g = self.gains
        R_FW = state.frame_pose(self.fid).rotation.T
        v_ref = np.concatenate([R_FW @ self.v_ref_W, np.zeros(3)])
        a_ref = np.concatenate([R_FW @ self.a_ref_W, np.zeros(3)])
        a_des = a_ref + g.kp * self.ik.compute_error(state) + g.kd * (v_ref - J @ state.v)
        return J, a_des - drift


class FramePositionAcceleration(_PointAcceleration):
    """Position of a frame origin in W (hands): ``J = J_F[:3]`` (LOCAL_WORLD_ALIGNED)."""

    def __init__(self, frame: str, model: pin.Model, gains: TaskGains, name: str | None = None):
        self.ik = FramePositionTask(frame, model, name=name)
        super().__init__(self.ik.name, 3, gains)
        self.fid = self.ik.frame_id
        self._init_references()

    def jacobian_and_drift(self, state: DynamicsState) -> tuple[np.ndarray, np.ndarray]:
        """``(J_F[:3], (Jdot_F v)[:3])`` in W-aligned axes."""
        ref = pin.LOCAL_WORLD_ALIGNED
        return state.frame_jacobian(self.fid, ref)[:3], state.frame_drift(self.fid, ref)[:3]


class PostureAcceleration(AccelerationTask):
    """Joint posture of the actuated joints: ``J = S`` (selection), error ``q ⊖ q_ref`` (IK task)."""

    def __init__(self, model: pin.Model, idx_v: npt.ArrayLike, gains: TaskGains, name: str = "posture"):
        self.idx_v = np.asarray(idx_v, dtype=int)
        super().__init__(name, len(self.idx_v), gains)
        self.ik = PostureTask(model, name=name)
        self._J = np.zeros((self.k, model.nv))
        self._J[np.arange(self.k), self.idx_v] = 1.0
        self._J.setflags(write=False)

    def set_reference(self, q: npt.ArrayLike) -> None:
        """Desired configuration (nq,), Pinocchio convention (only the actuated joints count)."""
        self.ik.set_target(q)

    def jacobian_and_drift(self, state: DynamicsState) -> tuple[np.ndarray, np.ndarray]:
        """``(S, 0)``."""
        return self._J, np.zeros(self.k)

    def rows(self, state: DynamicsState) -> tuple[np.ndarray, np.ndarray]:
        """Posture rows."""
        g = self.gains
        e = self.ik.compute_error(state)[self.idx_v]
        return self._J, -g.kp * e - g.kd * state.v[self.idx_v]


class AngularMomentumDamping(AccelerationTask):
    """Centroidal angular momentum to zero: ``J = A_g[3:]``, ``Jdot v = dA_g[3:] v``, a_des = -kd h."""

    def __init__(self, gains: TaskGains, name: str = "angular momentum"):
        super().__init__(name, 3, gains)

    def jacobian_and_drift(self, state: DynamicsState) -> tuple[np.ndarray, np.ndarray]:
        """``(A_g[3:], dA_g[3:] v)``."""
        return state.data.Ag[3:], state.data.dAg[3:] @ state.v

    def rows(self, state: DynamicsState) -> tuple[np.ndarray, np.ndarray]:
        """Angular-momentum rows (``kd`` from the gains; ``kp`` unused)."""
        J, drift = self.jacobian_and_drift(state)
        return J, -self.gains.kd * (J @ state.v) - drift
