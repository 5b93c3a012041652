"""What identification estimates for a robot: 10 inertial parameters per body, friction and armature.

Columns, in order: for each identified body B (a MuJoCo body of the robot), its 10 parameters
``pi_B`` about B's origin in B's axes (:mod:`~mbctl.robots.identification.inertial`), so an
estimate is written back into the MJCF body as it is; then, when asked, per actuated 1-dof joint
its viscous friction ``fv`` [N m s/rad] and Coulomb friction ``fc`` [N m], then its armature
``Ia`` [kg m^2]. Parameters that are not identified (the other bodies, including bodies welded
to a link and any payload of the log's plant that the nominal model lacks, and friction and
armature when not asked) keep their nominal values and enter the torques as known terms.

The joint torques are linear in the columns::

    tau = sum_B Y_J(B)(q, v, a) T_JB pi_B + diag(v) fv + diag(s(v)) fc + diag(a) Ia + tau_known

with ``Y_J`` the 10 columns of Pinocchio's joint-torque regressor of B's joint J,
``T_JB`` the change of frame from B to J's frame, and ``s(v) = tanh(v / v_s)``
(:data:`COULOMB_SMOOTHING_RAD_S`): MuJoCo's dry friction is a soft constraint that saturates
within a few mrad/s, which a sign function with a smooth zero crossing follows.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from mbctl.robots.edits import body_inertial
from mbctl.robots.exceptions import UnknownNameError
from mbctl.robots.identification.exceptions import IdentificationError
from mbctl.robots.identification.inertial import (
    INERTIAL_NAMES,
    from_inertial,
    pseudo_inertia,
    transform_matrix,
)
from mbctl.robots.model_pair import Robot

#: Velocity scale [rad/s] of the smooth sign in the Coulomb friction column.
COULOMB_SMOOTHING_RAD_S = 0.01

#: Relative change of a body's pseudo-inertia that the prior takes as one standard deviation.
PRIOR_RELATIVE = 0.5


@dataclass(frozen=True)
class BodyBlock:
    """One identified body.

    Attributes:
        name: MuJoCo body name.
        joint_id: Pinocchio joint the body moves with (its regressor block).
        transform: T (10, 10): the joint-frame parameters of the body are ``T @ pi_B``.
        nominal: ``pi_B`` (10,) of the nominal model, body frame.
        columns: Its 10 columns in the parameter vector.
    """

    name: str
    joint_id: int
    transform: np.ndarray
    nominal: np.ndarray
    columns: slice


@dataclass(frozen=True)
class JointBlock:
    """An actuated 1-dof joint with friction and/or armature columns.

    Attributes:
        name: Joint name.
        idx_v: Its index in v (Pinocchio convention).
        viscous: Column of fv [N m s/rad], or None.
        coulomb: Column of fc [N m], or None.
        armature: Column of Ia [kg m^2], or None.
    """

    name: str
    idx_v: int
    viscous: int | None
    coulomb: int | None
    armature: int | None


class ParameterSet:
    """The parameter vector of an identification on ``robot``, its names, nominal values and prior.

    Args:
        robot: The nominal model pair (its MuJoCo bodies and Pinocchio joints).
        bodies: Bodies to identify (default: every body of the robot with mass and a joint path to
            a moving joint; bodies welded to the world are left out).
        friction: Add viscous and Coulomb friction columns for each actuated 1-dof joint.
        armature: Add an armature column for each actuated 1-dof joint.

    Raises:
        UnknownNameError: A body the robot does not have.
        IdentificationError: A body without mass (log-Cholesky needs m > 0) or welded to the world.
    """

    def __init__(self, robot: Robot, bodies: Sequence[str] | None = None, friction: bool = False,
                 armature: bool = False):
        model = robot.pin_model
        self.model = model
        m = robot.mj_model
        ids = dict(zip(robot.bodies, robot.robot_body_ids, strict=True))
        joint_of: dict[str, tuple[int, pin.SE3]] = {}
        for name in robot.bodies:
            fid = model.getFrameId(name, pin.FrameType.BODY)
            frame = model.frames[fid]
            joint_of[name] = (int(frame.parentJoint), pin.SE3(frame.placement))
        movable = [b for b in robot.bodies if joint_of[b][0] > 0 and m.body_mass[ids[b]] > 0]
        if bodies is None:
            chosen = movable
        else:
            chosen = list(dict.fromkeys(bodies))
            for b in chosen:
                if b not in ids:
                    raise UnknownNameError("robot body", b, robot.bodies)
                if joint_of[b][0] == 0:
                    raise IdentificationError(f"body {b!r} is welded to the world: no joint torque "
                                              "depends on it; leave it out of --bodies")
                if not m.body_mass[ids[b]] > 0:
                    raise IdentificationError(f"body {b!r} has no mass in the nominal model; "
                                              "identification needs a positive nominal mass")
        names: list[str] = []
        nominal: list[float] = []
        blocks: list[BodyBlock] = []
        #: (njoints - 1, 10): joint-frame parameters of everything not identified
        self.known_joint_params = np.zeros((model.njoints - 1, 10))
        for name in robot.bodies:
            joint_id, X_JB = joint_of[name]
            if joint_id == 0:
                continue
            pi_B = from_inertial(*body_inertial(m, ids[name]))
            T = transform_matrix(X_JB)
            if name in chosen:
                cols = slice(len(names), len(names) + 10)
                blocks.append(BodyBlock(name, joint_id, T, pi_B, cols))
                names += [f"{name}.{p}" for p in INERTIAL_NAMES]
                nominal += pi_B.tolist()
            else:
                self.known_joint_params[joint_id - 1] += T @ pi_B
        self.bodies: tuple[BodyBlock, ...] = tuple(blocks)
        joints: list[JointBlock] = []
        actuated = [a.joint for a in robot.actuators.values() if a.joint]
        fc_nominal = np.asarray(model.upperDryFrictionLimit)
        for jname in dict.fromkeys(actuated):
            layout = robot.joint(jname)
            if layout.nv != 1:
                continue
            iv = layout.idx_v
            fv = fc = ia = None
            if friction:
                fv, fc = len(names), len(names) + 1
                names += [f"{jname}.fv", f"{jname}.fc"]
                nominal += [float(model.damping[iv]), float(fc_nominal[iv])]
            if armature:
                ia = len(names)
                names.append(f"{jname}.Ia")
                nominal.append(float(model.armature[iv]))
            joints.append(JointBlock(jname, iv, fv, fc, ia))
        self.joints: tuple[JointBlock, ...] = tuple(joints)
        self.names: tuple[str, ...] = tuple(names)
        self.nominal = np.array(nominal)
        self.nominal.setflags(write=False)
        # what stays at its nominal value: friction and armature when not identified
        self.known_damping = np.array(model.damping, dtype=float)
        self.known_coulomb = np.array(fc_nominal, dtype=float)
        self.known_armature = np.array(model.armature, dtype=float)
        for jb in joints:
            if jb.viscous is not None:
                self.known_damping[jb.idx_v] = 0.0
                self.known_coulomb[jb.idx_v] = 0.0
            if jb.armature is not None:
                self.known_armature[jb.idx_v] = 0.0
        self._check_against_model()

    def _check_against_model(self) -> None:
        """The bodies' parameters, summed per joint, must be the Pinocchio model's inertias."""
        total = self.known_joint_params.copy()
        for b in self.bodies:
            total[b.joint_id - 1] += b.transform @ b.nominal
        model = self.model
        expected = np.array([model.inertias[j].toDynamicParameters() for j in range(1, model.njoints)])
        err = float(np.abs(total - expected).max()) if len(expected) else 0.0
        if err > 1e-9 * max(1.0, float(np.abs(expected).max())):
            raise IdentificationError(
                f"the MuJoCo bodies' inertials do not add up to the Pinocchio model's (largest "
                f"difference {err:.3g}); the model pair must be built from the same MJCF")

    @property
    def n(self) -> int:
        """Number of parameters."""
        return len(self.names)

    def body(self, name: str) -> BodyBlock:
        """The identified body ``name``."""
        for b in self.bodies:
            if b.name == name:
                return b
        raise UnknownNameError("identified body", name, [b.name for b in self.bodies])

    def prior_factor(self) -> np.ndarray:
        """B (n, n) with the prior ``|B (theta - theta_0)|^2`` (a Gaussian of precision ``B^T B``).

        Each body's block is the second-order expansion of the entropic divergence between its
        pseudo-inertia J and the nominal ``J_0`` (Lee and Park's geometric regulariser):
        ``|J_0^-1/2 (J - J_0) J_0^-1/2|_F^2 / rho^2`` with rho = :data:`PRIOR_RELATIVE`. It measures
        a change relative to the body itself and in any frame: scaling a body's density by 1 +
        rho costs about as much as moving its CoM by its radius of gyration, and a thin link's small
        moments are as costly to change as its large ones in relative terms, so where the data
        cannot decide the body keeps its shape. Friction and armature: independent, standard
        deviation their nominal value (0.1 N m s/rad, 0.5 N m, 0.01 kg m^2 when it is zero).
        """
        out = np.zeros((self.n, self.n))
        basis = [pseudo_inertia(e) for e in np.eye(10)]
        for b in self.bodies:
            J0 = pseudo_inertia(b.nominal)
            w, V = np.linalg.eigh(J0)
            w = np.maximum(w, 1e-9 * w.max())  # a point mass is only semi-definite
            W = (V / np.sqrt(w)) @ V.T
            K = np.stack([(W @ P @ W).ravel() for P in basis], axis=1)  # (16, 10)
            L = np.linalg.cholesky(K.T @ K) / PRIOR_RELATIVE
            out[b.columns, b.columns] = L.T
        floors = {"viscous": 0.1, "coulomb": 0.5, "armature": 0.01}
        for jb in self.joints:
            for kind, col in (("viscous", jb.viscous), ("coulomb", jb.coulomb), ("armature", jb.armature)):
                if col is not None:
                    out[col, col] = 1.0 / max(abs(float(self.nominal[col])), floors[kind])
        return out

    def prior_std(self) -> np.ndarray:
        """Prior standard deviation (n,) of each parameter (the marginals of :meth:`prior_factor`)."""
        B = self.prior_factor()
        Binv = np.linalg.inv(B)
        return np.sqrt(np.sum(Binv**2, axis=1))

    def nonnegative(self) -> np.ndarray:
        """Mask (n,) of the scalar parameters that must be >= 0 (friction, armature)."""
        mask = np.zeros(self.n, dtype=bool)
        for jb in self.joints:
            for col in (jb.viscous, jb.coulomb, jb.armature):
                if col is not None:
                    mask[col] = True
        return mask

    # ------------------------------------------------------------------ regressor columns
    def columns(self, Y: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
        """The columns (nv, n) at one sample, from Pinocchio's regressor ``Y`` (nv, 10 (njoints-1)).

        Args:
            Y: ``pin.computeJointTorqueRegressor(model, data, q, v, a)``.
            v: Velocity (nv,).
            a: Acceleration (nv,).
        """
        out = np.zeros((Y.shape[0], self.n))
        for b in self.bodies:
            j = 10 * (b.joint_id - 1)
            out[:, b.columns] = Y[:, j:j + 10] @ b.transform
        for jb in self.joints:
            if jb.viscous is not None:
                out[jb.idx_v, jb.viscous] = v[jb.idx_v]
                out[jb.idx_v, jb.coulomb] = np.tanh(v[jb.idx_v] / COULOMB_SMOOTHING_RAD_S)
            if jb.armature is not None:
                out[jb.idx_v, jb.armature] = a[jb.idx_v]
        return out

    def known(self, Y: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
        """Generalized force (nv,) of everything not identified, at one sample (see :meth:`columns`)."""
        return (Y @ self.known_joint_params.ravel() + self.known_damping * v
                + self.known_coulomb * np.tanh(v / COULOMB_SMOOTHING_RAD_S) + self.known_armature * a)
