"""Physically consistent estimation, regularised toward the nominal model (a MAP estimate).

Minimise, over the parameter vector theta::

    |W theta - y|^2 / sigma^2  +  |B (theta - theta_0)|^2

the torque misfit (sigma: the torque noise, estimated from the residual of the unconstrained
least-squares fit) plus a Gaussian prior around the nominal model (B:
:meth:`ParameterSet.prior_factor`, per body the geometric, frame-invariant metric of its
pseudo-inertia). Where the data identify a direction the first term
decides; where they cannot (the null space) the prior keeps the nominal value. Every body's 10
parameters are the image of unconstrained log-Cholesky parameters (:mod:`inertial`), so the
minimiser is physically consistent by construction; friction and armature are bounded below by 0.

The problem is solved as a nonlinear least squares over the log-Cholesky parameters
(``scipy.optimize.least_squares``, trust-region reflective, Pinocchio's analytic Jacobian of the
log-Cholesky map): with A the quadratic's Hessian, the residual
is ``R_A theta - c`` with ``R_A^T R_A = A`` from a QR of the stacked data and prior rows.
When the unconstrained minimiser is already consistent it is the answer
and no iteration runs. The standard deviations are the Laplace approximation, ``diag(A^-1)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
from scipy.optimize import least_squares

from mbctl.robots.identification.exceptions import IdentificationError
from mbctl.robots.identification.inertial import (
    consistency_problems,
    from_log_cholesky,
    pseudo_inertia,
    to_log_cholesky,
)
from mbctl.robots.identification.parameters import ParameterSet
from mbctl.robots.identification.regressor import LinearSystem

#: Smallest torque noise [fraction of the RMS torque] assumed, so exact simulated data keep a
#: finite weight (the prior then still acts on the null space only).
SIGMA_FLOOR = 1e-6
#: Smallest pseudo-inertia eigenvalue [relative] at which the unconstrained estimate is accepted.
INTERIOR_RTOL = 1e-9


@dataclass(frozen=True)
class Estimate:
    """The identified parameters.

    Attributes:
        theta: Estimate (n,), physically consistent.
        std: Standard deviation (n,) (Laplace approximation; the prior's where data are silent).
        covariance: (n, n).
        sigma: Torque noise the fit assumed [N m] (RMS of the unconstrained fit's residual).
        iterations: Solver iterations (0: the unconstrained estimate was consistent).
        constrained: Whether the consistency constraints changed the estimate.
        cost_data: ``|W theta - y|^2`` at the estimate [N^2 m^2].
        cost_nominal: ``|W theta_0 - y|^2`` at the nominal model.
    """

    theta: np.ndarray
    std: np.ndarray
    covariance: np.ndarray
    sigma: float
    iterations: int
    constrained: bool
    cost_data: float
    cost_nominal: float


def noise_sigma(system: LinearSystem, rank: int) -> float:
    """RMS residual [N m] of the unconstrained least-squares fit, floored at :data:`SIGMA_FLOOR`."""
    theta, *_ = np.linalg.lstsq(system.R, system.z, rcond=None)
    dof = max(system.rows - rank, 1)
    rms = np.sqrt(max(system.residual_sq(theta), 0.0) / dof)
    floor = SIGMA_FLOOR * np.sqrt(system.y_sq / max(system.rows, 1))
    return float(max(rms, floor, 1e-300))


def _consistent(params: ParameterSet, theta: np.ndarray) -> bool:
    for b in params.bodies:
        J = pseudo_inertia(theta[b.columns])
        if np.linalg.eigvalsh(J)[0] <= INTERIOR_RTOL * np.abs(J).max():
            return False
    return bool(np.all(theta[params.nonnegative()] >= 0))


def estimate(params: ParameterSet, system: LinearSystem, rank: int, max_iterations: int = 200) -> Estimate:
    """The MAP estimate (see the module docstring).

    Args:
        params: The parameter set (nominal values, prior, bodies, non-negative scalars).
        system: The compressed equations ``W theta = y``.
        rank: The equations' numerical rank (for the noise estimate's degrees of freedom).
        max_iterations: Solver iterations at most.

    Raises:
        IdentificationError: The solver did not reach a consistent estimate.
    """
    theta0 = params.nominal.copy()
    B = params.prior_factor()
    s = params.prior_std()
    sigma = noise_sigma(system, rank)
    # scaled coordinates u = theta / s; the quadratic |[R / sigma; B] theta - [z / sigma; B theta0]|^2
    # is reduced by a QR (never forming R^T R, whose condition number is the square of the data's)
    n = params.n
    rows = np.vstack([system.R / sigma, B]) * s
    Q, RA = np.linalg.qr(rows)
    c = Q.T @ np.concatenate([system.z / sigma, B @ theta0])
    theta = scipy.linalg.solve_triangular(RA, c) * s
    iterations, constrained = 0, False
    if not _consistent(params, theta):
        theta, iterations = _solve_consistent(params, theta, theta0, s, RA, c, max_iterations)
        constrained = True
    RA_inv = scipy.linalg.solve_triangular(RA, np.eye(n))
    cov = (RA_inv @ RA_inv.T) * np.outer(s, s)
    return Estimate(theta, np.sqrt(np.diag(cov)), cov, sigma, iterations, constrained,
                    system.residual_sq(theta), system.residual_sq(theta0))


def _solve_consistent(params: ParameterSet, theta_map: np.ndarray, theta0: np.ndarray, s: np.ndarray,
                      RA: np.ndarray, rhs: np.ndarray, max_iterations: int) -> tuple[np.ndarray, int]:
    """Minimise |RA (theta / s) - rhs|^2 over log-Cholesky bodies and non-negative scalars.

    The start is the unconstrained estimate, with the bodies it makes inconsistent at nominal.
    """
    n = params.n
    body_cols = [b.columns for b in params.bodies]
    scalar = np.ones(n, dtype=bool)
    for cols in body_cols:
        scalar[cols] = False
    x0 = theta_map.copy()
    for cols in body_cols:
        inside = not consistency_problems(theta_map[cols])
        x0[cols] = to_log_cholesky(theta_map[cols] if inside else theta0[cols])
    nonneg = params.nonnegative()
    x0[nonneg] = np.maximum(x0[nonneg], 0.0)

    def theta_and_jac(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        theta = x.copy()
        dtheta = np.zeros((n, n))
        idx = np.flatnonzero(scalar)
        dtheta[idx, idx] = 1.0
        for cols in body_cols:
            theta[cols], dtheta[cols, cols] = from_log_cholesky(x[cols])
        return theta, dtheta

    def fun(x: np.ndarray) -> np.ndarray:
        theta, _ = theta_and_jac(x)
        return RA @ (theta / s) - rhs

    def jac(x: np.ndarray) -> np.ndarray:
        _, dtheta = theta_and_jac(x)
        return RA @ (dtheta / s[:, None])

    lower = np.where(nonneg, 0.0, -np.inf)
    result = least_squares(fun, x0, jac=jac, bounds=(lower, np.full(n, np.inf)), method="trf",
                           x_scale="jac", xtol=1e-10, ftol=1e-10, gtol=1e-10, max_nfev=max_iterations)
    theta, _ = theta_and_jac(result.x)
    bad = {b.name: consistency_problems(theta[b.columns]) for b in params.bodies}
    bad = {k: v for k, v in bad.items() if v}
    if bad or not np.all(np.isfinite(theta)):
        raise IdentificationError(f"the consistent estimate failed ({result.message}); bodies: {bad}")
    return theta, int(result.nfev)
