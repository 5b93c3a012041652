"""One body's 10 inertial parameters: conversions, frame changes, log-Cholesky, physical consistency.

The parameters of a body B about B's origin, in B's axes, in Pinocchio's order
(``pin.Inertia.toDynamicParameters``)::

    pi = (m, h_x, h_y, h_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz)    h = m c  [kg, kg m, kg m^2]

with ``I`` the rotational inertia about the origin (``I = I_c + m [c]x^T [c]x``). The joint-torque
regressor is linear in them. Physical consistency (a mass distribution with these moments exists)
is the positive definiteness of the 4x4 pseudo-inertia ``J = [[tr(I)/2 1 - I, h], [h^T, m]]``,
which implies m > 0, I_c positive definite and the triangle inequalities of the principal moments.
The log-Cholesky parameters ``xi`` (Rucker and Wensing 2022; Pinocchio's
``LogCholeskyParameters``: ``J = U U^T`` with U upper triangular, ``xi = (alpha, d1, d2, d3, s12,
s23, s13, t1, t2, t3)``) map all of R^10 onto the consistent set, so an unconstrained solver over
``xi`` can only return physical bodies.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pinocchio as pin

from mbctl.robots.identification.exceptions import InconsistentParameters

#: Parameter names within a body, Pinocchio's order.
INERTIAL_NAMES = ("m", "mcx", "mcy", "mcz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")
#: Index of the upper-triangle entries (0,0), (0,1), (1,1), (0,2), (1,2), (2,2) of I in pi[4:].
_I_INDEX = ((0, 0), (0, 1), (1, 1), (0, 2), (1, 2), (2, 2))
#: Relative tolerance of the consistency checks (round-off of a parameter vector at the boundary).
CONSISTENCY_RTOL = 1e-9


class Inertial(NamedTuple):
    """A body's inertial as a modeller writes it.

    Attributes:
        mass_kg: Mass [kg].
        com_m: Centre of mass (3,) [m] in the body frame.
        inertia_com: Rotational inertia (3, 3) [kg m^2] about the CoM, body axes.
    """

    mass_kg: float
    com_m: np.ndarray
    inertia_com: np.ndarray


def skew(v: np.ndarray) -> np.ndarray:
    """``[v]x`` (3, 3): ``skew(v) @ w == cross(v, w)``."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def rotational_inertia(pi: np.ndarray) -> np.ndarray:
    """I (3, 3) [kg m^2] about the origin from the parameters ``pi`` (10,)."""
    out = np.empty((3, 3))
    for k, (i, j) in enumerate(_I_INDEX):
        out[i, j] = out[j, i] = pi[4 + k]
    return out


def from_inertial(mass_kg: float, com_m: np.ndarray, inertia_com: np.ndarray) -> np.ndarray:
    """``pi`` (10,) of a body with this mass [kg], CoM (3,) [m] and inertia about the CoM (3, 3)."""
    c = np.asarray(com_m, dtype=float)
    I_o = np.asarray(inertia_com, dtype=float) + mass_kg * (c @ c * np.eye(3) - np.outer(c, c))
    return np.array([mass_kg, *(mass_kg * c), *(I_o[i, j] for i, j in _I_INDEX)])


def to_inertial(pi: np.ndarray) -> Inertial:
    """Mass, CoM and inertia about the CoM of ``pi`` (10,) (mass must be non-zero)."""
    m = float(pi[0])
    c = np.asarray(pi[1:4], dtype=float) / m
    return Inertial(m, c, rotational_inertia(pi) - m * (c @ c * np.eye(3) - np.outer(c, c)))


def spatial_matrix(pi: np.ndarray) -> np.ndarray:
    """The 6x6 spatial inertia (linear rows first, as ``pin.Inertia.matrix``), linear in ``pi``."""
    h = np.asarray(pi[1:4], dtype=float)
    out = np.zeros((6, 6))
    out[:3, :3] = pi[0] * np.eye(3)
    out[:3, 3:] = -skew(h)
    out[3:, :3] = skew(h)
    out[3:, 3:] = rotational_inertia(pi)
    return out


def from_spatial_matrix(M: np.ndarray) -> np.ndarray:
    """``pi`` (10,) of a 6x6 spatial inertia (inverse of :func:`spatial_matrix`)."""
    h = np.array([M[5, 1], M[3, 2], M[4, 0]])
    return np.array([M[0, 0], *h, *(M[3 + i, 3 + j] for i, j in _I_INDEX)])


def transform_matrix(X_AB: pin.SE3) -> np.ndarray:
    """T (10, 10) with ``pi_A = T pi_B``: the same body's parameters expressed in frame A.

    ``pi_B`` is about B's origin in B's axes; ``pi_A`` about A's origin in A's axes. Built
    column by column from the spatial inertia ``I_A = X_BA^T I_B X_BA`` (linear in ``pi_B``).
    """
    X_BA = X_AB.inverse().action
    out = np.empty((10, 10))
    for k in range(10):
        e = np.zeros(10)
        e[k] = 1.0
        out[:, k] = from_spatial_matrix(X_BA.T @ spatial_matrix(e) @ X_BA)
    return out


def pseudo_inertia(pi: np.ndarray) -> np.ndarray:
    """The 4x4 pseudo-inertia ``J`` of ``pi`` (positive definite iff physically consistent)."""
    Io = rotational_inertia(pi)
    J = np.empty((4, 4))
    J[:3, :3] = 0.5 * np.trace(Io) * np.eye(3) - Io
    J[:3, 3] = J[3, :3] = pi[1:4]
    J[3, 3] = pi[0]
    return J


def to_log_cholesky(pi: np.ndarray, floor: float = 1e-12) -> np.ndarray:
    """``xi`` (10,) with ``LogCholeskyParameters(xi).toDynamicParameters() == pi``.

    A body at the boundary of consistency (a point mass: J only semi-definite) is nudged inside by
    adding ``floor`` times its scale to J's diagonal, so a solver can start from it.

    Raises:
        InconsistentParameters: ``pi`` is not physically consistent (J has a negative eigenvalue).
    """
    J = pseudo_inertia(pi)
    lowest = float(np.linalg.eigvalsh(J)[0])
    scale = float(np.abs(J).max()) or 1.0
    if lowest < -CONSISTENCY_RTOL * scale:
        raise InconsistentParameters(
            f"parameters {np.round(pi, 9).tolist()} are not physically consistent (pseudo-inertia "
            f"eigenvalue {lowest:.3g}); no mass distribution has them")
    if lowest <= floor * scale:
        J = J + (floor * scale - min(lowest, 0.0)) * np.eye(4)
    flip = np.eye(4)[::-1]
    U = flip @ np.linalg.cholesky(flip @ J @ flip) @ flip  # upper triangular, J = U U^T
    alpha = np.log(U[3, 3])
    Un = U / U[3, 3]
    return np.array([alpha, np.log(Un[0, 0]), np.log(Un[1, 1]), np.log(Un[2, 2]), Un[0, 1], Un[1, 2],
                     Un[0, 2], Un[0, 3], Un[1, 3], Un[2, 3]])


def from_log_cholesky(xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``pi`` (10,) and ``d pi / d xi`` (10, 10) at ``xi`` (Pinocchio's LogCholeskyParameters)."""
    lc = pin.LogCholeskyParameters(np.asarray(xi, dtype=float))
    return np.array(lc.toDynamicParameters()), np.array(lc.calculateJacobian())


def consistency_problems(pi: np.ndarray) -> list[str]:
    """What makes ``pi`` unphysical, or [] (mass > 0, I_c positive definite, triangle inequalities).

    The tests are those a modeller checks, each with the numbers; a body passing all of them has a
    positive definite pseudo-inertia up to round-off.
    """
    m = float(pi[0])
    if not m > 0:
        return [f"mass {m:.6g} kg is not > 0"]
    _, c, I_c = to_inertial(pi)
    moments = np.linalg.eigvalsh(0.5 * (I_c + I_c.T))
    tol = CONSISTENCY_RTOL * max(float(moments.max()), 1e-30)
    out = []
    if moments[0] <= -tol:
        out.append(f"inertia about the CoM is not positive definite (principal moments "
                   f"{np.round(moments, 9).tolist()} kg m^2)")
    a, b, cc = moments
    if a + b < cc - tol:
        out.append(f"triangle inequality violated: {a:.6g} + {b:.6g} < {cc:.6g} kg m^2")
    return out
