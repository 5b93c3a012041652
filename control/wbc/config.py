"""Options of the whole-body QP and what one solve returns."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
import qpsolvers

from mbctl.control.exceptions import WBCSetupError

#: What the controller does when its QP has no solution.
ON_INFEASIBLE = ("raise", "damp")


@dataclass(frozen=True)
class WBCConfig:
    """Options of the whole-body QP.

    Attributes:
        f_min_n: Minimum normal force per contact point at full weight [N] (>= 0).
        f_max_n: Maximum normal force per contact point at full weight [N] (> f_min_n).
        contact_omega_rad_s: Natural frequency of the foot-drift feedback [rad/s] (>= 0).
        force_weight: Regularisation weight on the contact forces [cost]/[N].
        acceleration_weight: Regularisation weight on vdot [cost]/[rad/s^2].
        joint_limit_horizon_s: Horizon T [s] of the joint-limit acceleration bounds (> 0).
        joint_limit_margin_rad: The joint-limit bounds keep this far [rad or m] inside each joint's
            range (>= 0): the plant overshoots the model's accelerations a little (friction,
            armature, contacts), and a joint that reaches the plant's own limit gets an impulsive
            limit force (seen as a contact-force spike).
        joint_limit_max_accel_rad_s2: The joint-limit bounds never demand more than this [rad/s^2]
            toward the inside of a range (> 0), so they stay feasible under the torque limits even
            for a joint found past its bound.
        relax_joint_limits: On an infeasible QP, solve it again without the joint-limit
            acceleration bounds before ``on_infeasible`` applies (counted as a relaxed cycle). The
            bounds are a look-ahead that keeps joints off their stops; with torque limits, friction
            cones and the feet's constraints they can leave no solution for a cycle (an arm swinging
            toward its limit while the robot recovers from a push), and the plant's own joint limits
            still hold. False: the first infeasible QP applies ``on_infeasible``.
        ramp_s: Duration [s] of a contact's force ramp (> 0).
        solver: "daqp" (the structured solve of ``control/wbc/qp.py``: an equality-constrained fast
            path, else daqp) or another qpsolvers backend on the same problem (for comparison).
        force_space: With "daqp": when an inequality is active, first solve the QP in the contact
            forces alone (``control/wbc/force_space.py``; the same optimum to daqp's tolerance, its
            point checked against every row); False goes to daqp on the QP in vdot and forces.
        on_infeasible: "raise" (``WBCInfeasible``) or "damp": from the first infeasible QP on, the
            controller commands joint damping ``tau = -fallback_kd v`` (a safe fallback that lets
            the plant show whether the robot stands or falls) and records when it switched.
        fallback_kd_n_m_s_rad: Joint damping of the fallback [N m s/rad] (>= 0).
        friction_feedforward: Add the model's joint friction (Pinocchio's ``friction``, Coulomb,
            and ``damping``, viscous: the MJCF's ``frictionloss`` and ``damping``) to the QP's
            torques at the velocity the cycle plans, ``v + vdot dt``, then clamp to the torque
            limits. A loaded joint hardly notices; an unloaded limb (a free leg, a wrist) whose
            torques are below its dry friction sticks without it (e.g. 0.3 N m of frictionloss per joint).
        friction_speed_rad_s: Speed [rad/s] (> 0) at which the Coulomb term reaches 76 % of its
            value (``tanh(v / speed)``): a smooth sign, so a joint at rest gets none.
        torsion_m: Each foot's yaw moment about its sole's centre (the mean of its points) stays
            within ``torsion_m`` times its normal force [m] (> 0; ``inf``: unbounded). A sole of
            point contacts resists a yaw moment only by its points' friction, and less as its
            centre of pressure nears an edge.
    """

    f_min_n: float = 1.0
    f_max_n: float = 400.0
    contact_omega_rad_s: float = 10.0
    force_weight: float = 1e-4
    acceleration_weight: float = 1e-3
    joint_limit_horizon_s: float = 0.1
    joint_limit_margin_rad: float = 0.02
    joint_limit_max_accel_rad_s2: float = 50.0
    relax_joint_limits: bool = True
    ramp_s: float = 0.3
    solver: str = "daqp"
    force_space: bool = True
    on_infeasible: str = "raise"
    fallback_kd_n_m_s_rad: float = 5.0
    friction_feedforward: bool = False
    friction_speed_rad_s: float = 0.01
    torsion_m: float = math.inf

    def __post_init__(self) -> None:
        checks = {
            "f_min_n": self.f_min_n >= 0, "f_max_n": self.f_max_n > self.f_min_n,
            "contact_omega_rad_s": self.contact_omega_rad_s >= 0, "force_weight": self.force_weight > 0,
            "acceleration_weight": self.acceleration_weight > 0,
            "joint_limit_horizon_s": self.joint_limit_horizon_s > 0, "ramp_s": self.ramp_s > 0,
            "joint_limit_margin_rad": self.joint_limit_margin_rad >= 0,
            "joint_limit_max_accel_rad_s2": self.joint_limit_max_accel_rad_s2 > 0,
            "fallback_kd_n_m_s_rad": self.fallback_kd_n_m_s_rad >= 0,
            "friction_speed_rad_s": self.friction_speed_rad_s > 0,
        }
        if not self.torsion_m > 0:
            raise WBCSetupError(f"WBCConfig.torsion_m={self.torsion_m!r} is out of range (> 0 m, or inf)")
        for name, ok in checks.items():
            value = getattr(self, name)
            if not (np.isfinite(value) and ok):
                raise WBCSetupError(f"WBCConfig.{name}={value!r} is out of range")
        if self.solver not in qpsolvers.available_solvers:
            raise WBCSetupError(f"QP solver {self.solver!r} is not installed; available: "
                                f"{', '.join(sorted(qpsolvers.available_solvers))}")
        if self.on_infeasible not in ON_INFEASIBLE:
            raise WBCSetupError(f"WBCConfig.on_infeasible must be one of {', '.join(ON_INFEASIBLE)}; "
                                f"got {self.on_infeasible!r}")


def foot_totals_and_cops_W(forces_F: np.ndarray, X_WF: np.ndarray,
                           points_F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A foot's total contact force and centre of pressure in W, over b solutions at once.

    With the point forces in W ``f_P = R_WF f_FP``: the total is ``sum_P f_P``; the CoP is
    ``sum_P fz_P p_P / sum_P fz_P`` with ``p_P = R_WF p_FP + p_WF``, so the points are averaged in F
    and moved to W once (NaN where the total normal force is not above 1e-6 N).

    Args:
        forces_F: The points' forces (b, n_points, 3) [N] in F.
        X_WF: The foot frame's poses (b, 4, 4), homogeneous.
        points_F: The points (n_points, 3) [m] in F.

    Returns:
        The totals (b, 3) [N] and the CoPs (b, 3) [m], in W.
    """
    R = X_WF[:, :3, :3]
    total = np.einsum("bij,bj->bi", R, forces_F.sum(axis=1))
    fz_W = np.einsum("bpj,bj->bp", forces_F, R[:, 2])  # each point's force along W's z
    fz = total[:, 2:]
    loaded = fz > 1e-6
    with np.errstate(divide="ignore", invalid="ignore"):
        cop = np.einsum("bij,bj->bi", R, fz_W @ points_F) / np.where(loaded, fz, np.nan) + X_WF[:, :3, 3]
    return total, cop


@dataclass(frozen=True, init=False)
class WBCSolution:
    """What the last cycle commanded and the QP predicted.

    The QP's forces are in each foot's frame F; the world-frame views (``forces_W``, ``points_W``,
    ``foot_origins_W``, ``wrenches_W``, ``cop_W``) and the poses as Pinocchio objects
    (``foot_poses_W``) are computed when first read.

    Attributes:
        tau: Joint torques (n_actuated,) [N m], actuator order.
        vdot: Accelerations (nv,), Pinocchio convention (NaN under the fallback).
        forces: The QP's force variables (n_f,) [N], each foot's points in its frame F (zero under
            the fallback); by foot in ``forces_F``.
        force_slices: Each foot's entries of ``forces``, by foot name.
        points_F: Contact points by foot name, (n_points, 3) [m] in F.
        foot_X_W: Foot frame poses ``X_WF``, homogeneous (4, 4) each, feet in ``force_slices``' order
            (a log stacks many cycles' in one numpy call).
        wrench_map: (6 n_feet, n_f): the foot with index k (in ``force_slices``' order) has the
            wrench ``[f; m]`` about its frame's origin, in F, of rows 6k to 6k + 6 times ``forces``
            (the points' Jacobian map ``blockdiag(G_F)`` transposed).
        controller_time_s: Wall time of the whole ``compute`` [s], its torque command's checks included.
        qp_time_s: Wall time of the QP solve alone [s].
        fallback: The torques are the damping fallback's, not the QP's.
    """

    tau: np.ndarray
    vdot: np.ndarray
    forces: np.ndarray
    force_slices: dict[str, slice]
    points_F: dict[str, np.ndarray]
    foot_X_W: tuple[np.ndarray, ...]
    wrench_map: np.ndarray
    controller_time_s: float
    qp_time_s: float
    fallback: bool = False

    def __init__(self, tau: np.ndarray, vdot: np.ndarray, forces: np.ndarray, force_slices: dict[str, slice],
                 points_F: dict[str, np.ndarray], foot_X_W: tuple[np.ndarray, ...], wrench_map: np.ndarray,
                 controller_time_s: float, qp_time_s: float, fallback: bool = False) -> None:
        # Hand-written (the fields in one dict update): one is made every control cycle, and the
        # generated frozen __init__ sets each field through object.__setattr__ (~1.6 us against ~0.6)
        self.__dict__.update(tau=tau, vdot=vdot, forces=forces, force_slices=force_slices, points_F=points_F,
                             foot_X_W=foot_X_W, wrench_map=wrench_map,
                             controller_time_s=controller_time_s, qp_time_s=qp_time_s, fallback=fallback)

    @functools.cached_property
    def forces_F(self) -> dict[str, np.ndarray]:
        """Contact point forces by foot name, (n_points, 3) [N] in the foot's frame F."""
        return {name: self.forces[cols].reshape(-1, 3) for name, cols in self.force_slices.items()}

    @functools.cached_property
    def foot_poses_W(self) -> dict[str, pin.SE3]:
        """Foot frame poses ``X_WF`` by foot name (Pinocchio's, from ``foot_X_W``)."""
        return {name: pin.SE3(X) for name, X in zip(self.force_slices, self.foot_X_W, strict=True)}

    @functools.cached_property
    def forces_W(self) -> dict[str, np.ndarray]:
        """Contact point forces by foot name, (n_points, 3) [N] in W."""
        return {name: F @ X[:3, :3].T
                for (name, F), X in zip(self.forces_F.items(), self.foot_X_W, strict=True)}

    @functools.cached_property
    def points_W(self) -> dict[str, np.ndarray]:
        """Contact point positions by foot name, (n_points, 3) [m] in W."""
        return {name: self.points_F[name] @ X[:3, :3].T + X[:3, 3]
                for name, X in zip(self.force_slices, self.foot_X_W, strict=True)}

    @functools.cached_property
    def foot_origins_W(self) -> dict[str, np.ndarray]:
        """Foot frame origins by foot name, (3,) [m] in W."""
        return {name: X[:3, 3].copy() for name, X in zip(self.force_slices, self.foot_X_W, strict=True)}

    @functools.cached_property
    def wrenches_F(self) -> np.ndarray:
        """Each foot's wrench [f, m] [N, N m] about its frame's origin, in F, (n_feet, 2, 3).

        Feet in ``force_slices``' order; ``wrench_map`` times ``forces``.
        """
        return (self.wrench_map @ self.forces).reshape(-1, 2, 3)

    @functools.cached_property
    def wrenches_W(self) -> dict[str, np.ndarray]:
        """Foot wrench about the foot frame origin, in W, [f; m] (6,) [N, N m], by foot name."""
        return {name: (wrench @ X[:3, :3].T).ravel()
                for name, X, wrench in zip(self.force_slices, self.foot_X_W, self.wrenches_F, strict=True)}

    @functools.cached_property
    def _wrench_list(self) -> list[float]:
        """``wrenches_F`` flat, on plain floats: ``[f_F; m_F]`` per foot (its one product)."""
        return self.wrenches_F.ravel().tolist()

    @property
    def normal_forces_W(self) -> list[float]:
        """Each foot's total contact force's z [N] in W, feet in ``force_slices``' order (plain floats)."""
        w = self._wrench_list
        out = []
        for k, X in enumerate(self.foot_X_W):
            r20, r21, r22, _ = X[2].tolist()
            out.append(r20 * w[6 * k] + r21 * w[6 * k + 1] + r22 * w[6 * k + 2])
        return out

    def moment_about_W(self, point_W: np.ndarray) -> tuple[np.ndarray, float]:
        """The contact forces' total moment (3,) [N m] about ``point_W`` (3,) [m] and their total z [N], in W.

        About the CoM the moment is the rate of the centroidal angular momentum the QP planned.
        Each foot: ``R m_F + (t - point) x R f_F`` from the wrenches in F (one product), on plain floats
        (a walker reads it every cycle: ~4 us warm against ~8 with a 3 x 3 product per foot, and
        ``np.cross`` costs ~10 us a call at this size).
        """
        cx, cy, cz = point_W.tolist()
        wrenches = self._wrench_list  # [f_F; m_F] per foot
        mx = my = mz = fz = 0.0
        for k, X in enumerate(self.foot_X_W):
            (r00, r01, r02, tx), (r10, r11, r12, ty), (r20, r21, r22, tz), _ = X.tolist()
            fx, fy, fz_F, ux, uy, uz = wrenches[6 * k:6 * k + 6]
            ax, ay, az = (r00 * fx + r01 * fy + r02 * fz_F, r10 * fx + r11 * fy + r12 * fz_F,
                          r20 * fx + r21 * fy + r22 * fz_F)  # R f_F
            bx, by, bz = (r00 * ux + r01 * uy + r02 * uz, r10 * ux + r11 * uy + r12 * uz,
                          r20 * ux + r21 * uy + r22 * uz)  # R m_F
            rx, ry, rz = tx - cx, ty - cy, tz - cz
            mx += bx + ry * az - rz * ay
            my += by + rz * ax - rx * az
            mz += bz + rx * ay - ry * ax
            fz += az
        return np.array([mx, my, mz]), fz

    @functools.cached_property
    def totals_and_cops_W(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Each foot's total force and centre of pressure in W, in one pass (a log reads both every cycle).

        With the point forces in W ``f_P = R_WF f_FP``: the total is ``sum_P f_P``; the CoP is
        ``sum_P fz_P p_P / sum_P fz_P`` with ``p_P = R_WF p_FP + p_WF``, so the points are averaged
        in F and moved to W once.
        """
        out = {}
        for (name, F), X in zip(self.forces_F.items(), self.foot_X_W, strict=True):
            total, cop = foot_totals_and_cops_W(F[None], X[None], self.points_F[name])
            out[name] = (total[0], cop[0])
        return out

    @property
    def force_totals_W(self) -> dict[str, np.ndarray]:
        """Each foot's total contact force (3,) [N] in W, by foot name."""
        return {name: tc[0] for name, tc in self.totals_and_cops_W.items()}

    @property
    def cop_W(self) -> dict[str, np.ndarray]:
        """Centre of pressure (3,) [m] in W by foot name (NaN for a foot without normal force)."""
        return {name: tc[1] for name, tc in self.totals_and_cops_W.items()}
