"""Task states: one set of Pinocchio passes per configuration, read by every task.

Two states share one read side (:class:`TaskState`: frame poses, frame Jacobians, the centre of
mass and its Jacobian) and differ in what ``update`` computes:

* :class:`KinematicState` ``update(q)``, for differential IK: forward kinematics and every joint
  Jacobian (``pin.computeJointJacobians``, or, when a task needs the CoM and its Jacobian,
  ``pin.jacobianCenterOfMass``, which computes the joint Jacobians too) and
  ``pin.updateFramePlacements``.
* :class:`DynamicsState` ``update(q, v)``, for inverse dynamics: ``pin.computeAllTerms`` (M, the
  bias forces, the joint Jacobians, the CoM and its Jacobian, and the body accelerations at zero
  vdot, i.e. the drifts ``Jdot v``, the centroidal map ``A_g`` and its time variation ``dA_g``)
  and the frame placements.

The two are siblings, not parent and child: their ``update`` signatures differ, so neither can
stand in for the other where an update is called.

Conventions are Pinocchio's (the toolkit's public convention): q stores free-flyer quaternions
as (x, y, z, w) and v is the base velocity in the base (local) frame. Notation (Drake monograms):
W world, F a frame, C the centre of mass.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from mbctl.control.exceptions import TaskSetupError
from mbctl.robots.exceptions import UnknownNameError


class TaskState:
    """Configuration ``q`` of a Pinocchio model and the kinematic quantities tasks read.

    Attributes:
        model: The Pinocchio model (not modified).
        data: Pinocchio data, written by ``update``.
        oMf: ``data.oMf``, the frame placements ``X_WF`` (bound once for the hot path).
        frame_placements: ``X_WF`` of each frame by id: live references into ``data.oMf`` made
            once (each ``oMf[i]`` read makes a new reference, ~0.3 us).
    """

    def __init__(self, model: pin.Model):
        self.model = model
        self.data = model.createData()
        self._q = pin.neutral(model)
        self._q_view = self._q.view()  # _q is only ever written in place: one view serves
        self._q_view.setflags(write=False)
        self.oMf = self.data.oMf  # a reference into data, stable for its lifetime
        self.frame_placements = tuple(self.oMf[i] for i in range(model.nframes))
        # views into data (Pinocchio writes these in place, never reallocates them): one attribute
        # read instead of two binding calls per step
        self._com = self.data.com[0]
        self._Jcom = self.data.Jcom.reshape(3, -1)  # (3,) from the bindings when nv = 1

    @property
    def q(self) -> np.ndarray:
        """Current configuration (nq,) (a read-only view, updated in place by ``update``)."""
        return self._q_view

    @property
    def nq(self) -> int:
        """Configuration dimension."""
        return self.model.nq

    @property
    def nv(self) -> int:
        """Tangent dimension."""
        return self.model.nv

    def _set_q(self, q: npt.ArrayLike) -> np.ndarray:
        """Copy ``q`` into the state's buffer after checking its shape and finiteness.

        Raises:
            TaskSetupError: ``q`` has the wrong shape or non-finite entries.
        """
        q_new = self._q
        try:
            q_new[:] = q
        except (ValueError, TypeError) as exc:
            raise TaskSetupError(f"q must be a finite vector of shape ({self.model.nq},); got {q!r}") from exc
        if not math.isfinite(q_new @ q_new):  # any nan/inf (or an absurd magnitude)
            raise TaskSetupError(f"q must be finite (and of sane magnitude, |q| < 1e150); "
                                 f"got {q_new.tolist()}")
        return q_new

    def frame_id(self, name: str) -> int:
        """Pinocchio frame id of ``name`` (body, site or added operational frame).

        Raises:
            UnknownNameError: No such frame (the message lists close matches).
        """
        if not self.model.existFrame(name):
            raise UnknownNameError("frame", name, [f.name for f in self.model.frames])
        return self.model.getFrameId(name)

    def frame_pose(self, frame_id: int) -> pin.SE3:
        """Pose ``X_WF`` of frame ``frame_id`` in the world."""
        return self.frame_placements[frame_id]

    def frame_jacobian(self, frame_id: int, reference: pin.ReferenceFrame = pin.LOCAL) -> np.ndarray:
        """``J_F`` (6, nv) of frame ``frame_id``, [v; w], expressed in ``reference``."""
        J = pin.getFrameJacobian(self.model, self.data, frame_id, reference)
        # with nv = 1, Pinocchio's bindings return the matrix as a (6,) vector
        return J if J.ndim == 2 else J.reshape(6, -1)

    def com(self) -> np.ndarray:
        """Centre of mass ``p_WC`` (3,) [m] (a view into the data)."""
        return self._com

    def com_jacobian(self) -> np.ndarray:
        """CoM Jacobian (3, nv) [m/rad or m/m] in the world frame (a view into the data)."""
        return self._Jcom


class KinematicState(TaskState):
    """``q`` with frame placements, joint Jacobians and (optionally) the CoM: the IK state.

    Attributes:
        with_com: Whether ``update`` also computes the CoM and its Jacobian.
    """

    def __init__(self, model: pin.Model, q: npt.ArrayLike | None = None, with_com: bool = True):
        """Create the state at ``q`` (default: the model's neutral configuration).

        Args:
            model: Pinocchio model.
            q: Initial configuration (nq,), Pinocchio convention.
            with_com: Compute the centre of mass and its Jacobian (3, nv) on every update.
        """
        super().__init__(model)
        self.with_com = with_com
        self.update(self._q if q is None else q)

    def update(self, q: npt.ArrayLike) -> None:
        """Set ``q`` (nq,) and recompute frame placements, joint Jacobians and (optionally) CoM.

        Raises:
            TaskSetupError: ``q`` has the wrong shape or non-finite entries.
        """
        q_new = self._set_q(q)
        model, data = self.model, self.data
        if self.with_com:
            # one pass: forward kinematics, every joint Jacobian (data.J, as computeJointJacobians;
            # Pinocchio's center-of-mass.hpp documents it), the CoM and its Jacobian (~1 us less
            # than the two passes, bit-identical)
            pin.jacobianCenterOfMass(model, data, q_new, False)
        else:
            pin.computeJointJacobians(model, data, q_new)
        pin.updateFramePlacements(model, data)

    def integrate(self, v: npt.ArrayLike, dt: float) -> np.ndarray:
        """``pin.integrate(q, v dt)``: the configuration (nq,) after moving along ``v`` for ``dt`` [s]."""
        return pin.integrate(self.model, self._q, np.asarray(v, dtype=float) * dt)


class DynamicsState(TaskState):
    """``(q, v)`` with every term inverse dynamics needs, from one set of Pinocchio passes.

    Attributes:
        v: Velocity (nv,), Pinocchio convention (base twist in the base frame).
        qv: ``[q; v]`` (nq + nv,): the buffer ``q`` and ``v`` are views of (read-only; one product
            reads both, e.g. a linear map of the state).
        mass: Total mass [kg].
    """

    def __init__(self, model: pin.Model, q: npt.ArrayLike | None = None, v: npt.ArrayLike | None = None):
        """Create the state at ``(q, v)`` (defaults: the neutral configuration, at rest)."""
        super().__init__(model)
        # q and v in one buffer: one product checks both for finiteness per update
        self._qv = np.concatenate([self._q, np.zeros(model.nv)])
        self._q = self._qv[:model.nq]
        self._q_view = self._q.view()
        self._q_view.setflags(write=False)
        self.v = self._qv[model.nq:]
        self.qv = self._qv.view()
        self.qv.setflags(write=False)
        self._M_buffer = np.zeros((model.nv, model.nv))
        self._M_view = self._M_buffer.view()
        self._M_view.setflags(write=False)
        self._M: np.ndarray | None = None
        self._centroidal_drift: np.ndarray | None = None
        # a free-flyer root (joint 1, the only child of the universe): its rows of the dynamics
        # are the whole robot's momentum balance, which gives dA_g v without another pass
        self._free_root = (model.njoints > 1 and model.joints[1].shortname() == "JointModelFreeFlyer"
                           and list(model.parents[1:]).count(0) == 1)
        self._on_root = tuple(self._free_root and f.parentJoint == 1 for f in model.frames)
        self.mass = float(pin.computeTotalMass(model))  # the moving bodies (not the universe's)
        # read every cycle: references into data made once (Pinocchio writes them in place), and
        # the model's gravity and 1/m (fixed, as the mass above)
        self._X_WB = self.data.oMi[1] if self._free_root else None
        self._nle_linear = self.data.nle[:3]
        self._gravity_xyz = tuple(np.array(model.gravity.linear).tolist())
        self._inv_mass = 1.0 / self.mass if self.mass > 0.0 else math.inf
        self.update(self._q if q is None else q, v)

    def update(self, q: npt.ArrayLike, v: npt.ArrayLike | None = None) -> None:
        """Set ``q`` (nq,) and ``v`` (nv,) (default: zero) and recompute every term.

        Raises:
            TaskSetupError: ``q`` or ``v`` of the wrong shape or not finite.
        """
        q_new, v_new = self._q, self.v
        try:
            q_new[:] = q
        except (ValueError, TypeError) as exc:
            raise TaskSetupError(f"q must be a finite vector of shape ({self.model.nq},); got {q!r}") from exc
        if v is None:
            v_new[:] = 0.0
        else:
            try:
                v_new[:] = v
            except (ValueError, TypeError) as exc:
                raise TaskSetupError(f"v must be a finite vector of shape ({self.model.nv},); "
                                     f"got {v!r}") from exc
        if not math.isfinite(self._qv @ self._qv):  # any nan/inf in q or v (or an absurd magnitude)
            self._set_q(q_new)  # raises for q
            raise TaskSetupError(f"v must be finite (and of sane magnitude, |v| < 1e150); "
                                 f"got {v_new.tolist()}")
        model, data = self.model, self.data
        pin.computeAllTerms(model, data, q_new, self.v)  # also A_g (data.Ag)
        pin.updateFramePlacements(model, data)
        self._M = None
        self._centroidal_drift = None

    @property
    def M(self) -> np.ndarray:  # noqa: N802 - the mass matrix is M in every text
        """Joint-space inertia (nv, nv) at q, both triangles filled (read-only, once per update)."""
        if self._M is None:
            self.mass_matrix_into(self._M_buffer)
            self._M = self._M_view
        return self._M

    def mass_matrix_into(self, out: np.ndarray) -> None:
        """Write the joint-space inertia (nv, nv), both triangles, into ``out`` (e.g. a block of rows)."""
        # Pinocchio's Python computeAllTerms mirrors M's upper triangle (all its C++ algorithm writes)
        # into the lower one (its binding's proxy), so after update data.M is whole and symmetric
        # (tested): one copy, of its transpose, read in memory order (the mirror by a masked copy
        # cost ~1.3 us more)
        np.copyto(out, self.data.M.T)

    @property
    def b(self) -> np.ndarray:
        """Bias forces (nv,) [N m]: Coriolis, centrifugal and gravity, ``C(q, v) v + g(q)``."""
        return self.data.nle

    def com_drift(self) -> np.ndarray:
        """``Jdot_com v`` (3,) [m/s^2]: the CoM acceleration at zero vdot.

        With a free-flyer root, the linear rows of :meth:`centroidal_drift` alone: ``R_WB b_B[:3] / m
        + g`` (the CoM task needs no angular part: ~5 us less per cycle on a 35-dof humanoid).
        """
        return np.array(self.com_drift_xyz())

    def com_drift_xyz(self) -> tuple[float, float, float]:
        """:meth:`com_drift` as three floats (x, y, z) [m/s^2] in W.

        With a free-flyer root on plain floats: a 3 x 3 product and two (3,) operations in numpy
        cost ~0.5 us a call, nine products and sums in Python ~0.3 us together.
        """
        if self._X_WB is not None and self._centroidal_drift is None:
            (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = self._X_WB.rotation.tolist()
            bx, by, bz = self._nle_linear.tolist()
            k = self._inv_mass
            gx, gy, gz = self._gravity_xyz
            return ((r00 * bx + r01 * by + r02 * bz) * k + gx, (r10 * bx + r11 * by + r12 * bz) * k + gy,
                    (r20 * bx + r21 * by + r22 * bz) * k + gz)
        x, y, z = (self.centroidal_drift()[:3] / self.mass).tolist()
        return x, y, z

    def frame_drift(self, frame_id: int, reference: pin.ReferenceFrame) -> np.ndarray:
        """``d/dt(J_F) v`` (6,) in ``reference``: the frame's acceleration at zero vdot.

        In LOCAL, the derivative of the body twist is the spatial acceleration; in
        LOCAL_WORLD_ALIGNED (and WORLD-aligned linear rows) it is the classical acceleration of
        the frame origin.
        """
        if reference == pin.LOCAL:
            return pin.getFrameAcceleration(self.model, self.data, frame_id, reference).vector
        return pin.getFrameClassicalAcceleration(self.model, self.data, frame_id, reference).vector

    def frame_angular_drift(self, frame_id: int) -> np.ndarray:
        """The angular rows of ``frame_drift(frame_id, LOCAL)`` (3,) [rad/s^2], in F."""
        return pin.getFrameAcceleration(self.model, self.data, frame_id, pin.LOCAL).angular

    def on_free_root(self, frame_id: int) -> bool:
        """Whether frame ``frame_id`` is fixed to a free-flyer root body.

        Its LOCAL Jacobian is then the same at every state (the root's twist is ``v[:6]`` in its
        own frame) and its LOCAL drift is zero (the root's spatial acceleration at zero vdot is
        ``v x v = 0``).
        """
        return self._on_root[frame_id]

    def centroidal_map(self) -> np.ndarray:
        """``A_g`` (6, nv): the centroidal momentum ``h_G = A_g v`` [kg m/s; kg m^2/s] (about the CoM)."""
        return self.data.Ag

    def centroidal_drift(self) -> np.ndarray:
        """``dA_g v`` (6,): the rate of centroidal momentum at zero vdot [N; N m] (once per update).

        ``pin.computeAllTerms`` computes ``dA_g`` in its pass (Pinocchio 4.1's backward step, as
        ``computeCentroidalMapTimeVariation`` does: tested against it), so this is one product
        (~1.3 us against ~8.5 for the root's bias wrench moved to the CoM, done here before).
        """
        if self._centroidal_drift is None:
            self._centroidal_drift = self.data.dAg @ self.v
        return self._centroidal_drift

    def angular_momentum(self) -> np.ndarray:
        """``h_G`` angular part (3,) [kg m^2/s]: the angular momentum about the CoM, ``A_g[3:] v``."""
        return self.data.hg.angular
