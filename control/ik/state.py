"""Kinematic state for differential IK: one Pinocchio pass per configuration.

``IKState.update(q)`` runs ``pin.computeJointJacobians`` (forward kinematics plus all joint
Jacobians), ``pin.updateFramePlacements`` and, when a task needs it, the centre of mass and its
Jacobian. Every task then reads frame poses and Jacobians from the same ``pin.Data`` without
another tree pass.

Conventions are Pinocchio's (the toolkit's public convention): q stores free-flyer quaternions
as (x, y, z, w) and v is the base velocity in the base (local) frame.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from mbctl.control.exceptions import IKSetupError
from mbctl.robots.exceptions import UnknownNameError


class IKState:
    """Configuration ``q`` of a Pinocchio model with the kinematic quantities the tasks need.

    Attributes:
        model: The Pinocchio model (not modified).
        data: Pinocchio data, updated by ``update``.
        with_com: Whether ``update`` also computes the CoM and its Jacobian.
    """

    def __init__(self, model: pin.Model, q: npt.ArrayLike | None = None, with_com: bool = True):
        """Create the state; ``q`` defaults to the model's neutral configuration.

        Args:
            model: Pinocchio model.
            q: Initial configuration (nq,), Pinocchio convention.
            with_com: Compute the centre of mass and its Jacobian (3, nv) on every update.
        """
        self.model = model
        self.data = model.createData()
        self.with_com = with_com
        self._q = pin.neutral(model)
        # References into ``data`` (stable for its lifetime), fetched once for the hot path.
        self.oMf = self.data.oMf
        self.update(self._q if q is None else q)

    @property
    def q(self) -> np.ndarray:
        """Current configuration (nq,) (a read-only view)."""
        view = self._q.view()
        view.setflags(write=False)
        return view

    @property
    def nq(self) -> int:
        """Configuration dimension."""
        return self.model.nq

    @property
    def nv(self) -> int:
        """Tangent dimension."""
        return self.model.nv

    def update(self, q: npt.ArrayLike) -> None:
        """Set ``q`` (nq,) and recompute frame placements, joint Jacobians and (optionally) CoM.

        Raises:
            IKSetupError: ``q`` has the wrong shape or non-finite entries.
        """
        q_new = self._q
        try:
            q_new[:] = q
        except (ValueError, TypeError) as exc:
            raise IKSetupError(
                f"q must be a finite vector of shape ({self.model.nq},); got {q!r}"
            ) from exc
        if not math.isfinite(q_new @ q_new):  # any nan/inf (or an absurd magnitude)
            raise IKSetupError(
                f"q must be finite (and of sane magnitude, |q| < 1e150); got {q_new.tolist()}"
            )
        model, data = self.model, self.data
        pin.computeJointJacobians(model, data, q_new)
        pin.updateFramePlacements(model, data)
        if self.with_com:
            pin.jacobianCenterOfMass(model, data, False)

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
        return self.oMf[frame_id]

    def frame_jacobian_local(self, frame_id: int) -> np.ndarray:
        """Body Jacobian ``J_F`` (6, nv): the frame's twist in its own frame, [v; w]."""
        # reshape: with nv = 1, Pinocchio's bindings return the matrix as a (6,) vector
        return pin.getFrameJacobian(self.model, self.data, frame_id, pin.LOCAL).reshape(6, -1)

    def com(self) -> np.ndarray:
        """Centre of mass ``p_WC`` (3,) [m] (needs ``with_com``)."""
        return self.data.com[0]

    def com_jacobian(self) -> np.ndarray:
        """CoM Jacobian (3, nv) [m/rad or m/m] in the world frame (needs ``with_com``)."""
        return self.data.Jcom.reshape(3, -1)  # (3,) from the bindings when nv = 1

    def integrate(self, v: npt.ArrayLike, dt: float) -> np.ndarray:
        """``pin.integrate(q, v dt)``: the configuration after moving along ``v`` for ``dt``."""
        return pin.integrate(self.model, self._q, np.asarray(v, dtype=float) * dt)

    def integrate_inplace(self, v: npt.ArrayLike, dt: float) -> None:
        """Integrate on the manifold and update."""
        self.update(self.integrate(v, dt))
