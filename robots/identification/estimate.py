"""Physically consistent estimation, regularised toward the nominal model (a MAP estimate).

Minimise, over the parameter vector theta::

    |W theta - y|^2 / sigma^2  +  |B (theta - theta_0)|^2
    subject to  J_b(theta) > 0 for every body b,  friction and armature >= 0

the torque misfit (sigma: the torque noise, estimated from the residual of the unconstrained
least-squares fit) plus a Gaussian prior around the nominal model (B:
:meth:`ParameterSet.prior_factor`, per body the geometric, frame-invariant metric of its
pseudo-inertia). Where the data identify a direction the first term decides; where they cannot
(the null space) the prior keeps the nominal body, deformed as little as the identified
combinations require. The constraint is the LMI of physical consistency: the 4x4 pseudo-inertia
J_b, linear in the body's parameters, positive definite (mass > 0, inertia positive definite,
triangle inequalities, a density that exists).

The quadratic is reduced once by a QR of the stacked data and prior rows (``R_A theta - c``,
never forming the normal equations). When its unconstrained minimiser is already consistent it
is the answer and no iteration runs; otherwise a log-det barrier (interior-point) Newton method
solves the convex LMI problem to its global minimum (:func:`_solve_consistent`). The standard
deviations are the Laplace approximation at the estimate, ``diag(A^-1)`` of the quadratic's
Hessian A (the constraints' curvature left out).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

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
#: The barrier method stops when mu times the barrier's order is below this fraction of the
#: objective (the gap to the constrained optimum).
GAP_TOL = 1e-9


@dataclass(frozen=True)
class Estimate:
    """The identified parameters.

    Attributes:
        theta: Estimate (n,), physically consistent.
        std: Standard deviation (n,) (Laplace approximation; the prior's where data are silent;
            :func:`~mbctl.robots.identification.pipeline.identify` replaces it with the
            residual-aware one of :mod:`~mbctl.robots.identification.uncertainty`).
        covariance: (n, n), the same.
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
    return (all(_strictly_inside(theta[b.columns]) for b in params.bodies)
            and bool(np.all(theta[params.nonnegative()] >= 0)))


def estimate(params: ParameterSet, system: LinearSystem, rank: int, max_iterations: int = 500) -> Estimate:
    """The MAP estimate (see the module docstring).

    Args:
        params: The parameter set (nominal values, prior, bodies, non-negative scalars).
        system: The compressed equations ``W theta = y``.
        rank: The equations' numerical rank (for the noise estimate's degrees of freedom).
        max_iterations: Newton steps at most.

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
    """Minimise ``|RA u - rhs|^2 / 2`` (u = theta / s) with every body's pseudo-inertia J_b > 0.

    The constraints are linear matrix inequalities (J is linear in theta) and the objective is
    convex, so a log-det barrier method finds the global minimum: Newton steps on
    ``f(u) - mu (sum_b log det J_b + sum_i log u_i)`` (the friction and armature scalars),
    mu divided by 10 once each centring converges, until ``mu`` times the barrier's order is below
    :data:`GAP_TOL` of the objective. Hand-written because no LMI solver is a dependency here and
    the problem is small (n <= a few hundred, 4x4 blocks). The start is the unconstrained
    estimate with the bodies it makes inconsistent at their (strictly consistent) nominal.

    Returns:
        theta, and the number of Newton steps taken.
    """
    n = params.n
    basis = np.stack([pseudo_inertia(e) for e in np.eye(10)])  # J = sum_k pi_k basis_k
    bodies = [(b.columns, basis * s[b.columns][:, None, None]) for b in params.bodies]  # in u
    nonneg = np.flatnonzero(params.nonnegative())
    u = theta_map / s
    for cols, _ in bodies:
        if consistency_problems(theta_map[cols]) or not _strictly_inside(theta_map[cols]):
            u[cols] = from_log_cholesky(to_log_cholesky(theta0[cols]))[0] / s[cols]
    u[nonneg] = np.maximum(u[nonneg], 1e-6)
    order = 4 * len(bodies) + len(nonneg)
    blocks = [np.arange(n)[cols] for cols, _ in bodies] + [np.array([i]) for i in nonneg]

    def barrier(u: np.ndarray, with_derivatives: bool = True
                ) -> tuple[float, np.ndarray | None, np.ndarray | None]:
        """-(sum log det J_b + sum log u_i), its gradient and Hessian (inf outside the domain)."""
        value = 0.0
        grad = np.zeros(n) if with_derivatives else None
        hess = np.zeros((n, n)) if with_derivatives else None
        for cols, P in bodies:
            J = np.einsum("k,kij->ij", u[cols], P)
            try:
                L = np.linalg.cholesky(J)
            except np.linalg.LinAlgError:
                return np.inf, None, None
            value -= 2.0 * float(np.log(np.diag(L)).sum())
            if with_derivatives:
                M = np.linalg.solve(J, P)  # J^-1 P_k, (10, 4, 4)
                grad[cols] = -np.einsum("kii->k", M)  # type: ignore[index]
                hess[cols, cols] = np.einsum("kij,lji->kl", M, M)  # type: ignore[index]
        if len(nonneg):
            x = u[nonneg]
            if np.any(x <= 0):
                return np.inf, None, None
            value -= float(np.log(x).sum())
            if with_derivatives:
                grad[nonneg] -= 1.0 / x  # type: ignore[index]
                hess[nonneg, nonneg] += 1.0 / x**2  # type: ignore[index]
        return value, grad, hess

    def objective(u: np.ndarray) -> float:
        r = RA @ u - rhs
        return 0.5 * float(r @ r)

    mu = max(1.0, objective(u)) / order
    steps = 0
    while True:
        for _ in range(50):  # centring: Newton on f + mu barrier
            phi, g_b, H_b = barrier(u)
            assert g_b is not None and H_b is not None  # u is strictly feasible here
            grad = RA.T @ (RA @ u - rhs) + mu * g_b
            # the Newton step as a least-squares problem (the data rows are never squared):
            # min |RA (u + d) - rhs|^2 + mu (g_b . d + d^T H_b d / 2), H_b = C^T C
            C, c_b = np.zeros((n, n)), np.zeros(n)
            for idx in blocks:  # H_b is block diagonal: one body, or one scalar, per block
                C[np.ix_(idx, idx)], c_b[idx] = _square_root(H_b[np.ix_(idx, idx)], g_b[idx])
            K = np.vstack([RA, np.sqrt(mu) * C])
            r = np.concatenate([rhs - RA @ u, -np.sqrt(mu) * c_b])
            Q, R = np.linalg.qr(K)
            step = scipy.linalg.solve_triangular(R, Q.T @ r)
            decrement = -float(grad @ step)
            steps += 1
            if decrement < 1e-10 * max(1.0, objective(u)):
                break
            value = objective(u) + mu * phi
            t = 1.0
            while t > 1e-12:
                candidate = u + t * step
                phi_c = barrier(candidate, with_derivatives=False)[0]
                if np.isfinite(phi_c) and objective(candidate) + mu * phi_c <= value - 0.25 * t * decrement:
                    break
                t *= 0.5
            u = u + t * step
            if steps >= max_iterations:
                break
        if mu * order < GAP_TOL * max(1.0, objective(u)) or steps >= max_iterations:
            break
        mu /= 10.0
    theta = u * s
    bad = {b.name: consistency_problems(theta[b.columns]) for b in params.bodies}
    bad = {k: v for k, v in bad.items() if v}
    if bad or not np.all(np.isfinite(theta)):
        raise IdentificationError(f"the consistent estimate failed after {steps} Newton steps; bodies: {bad}")
    return theta, steps


def _strictly_inside(pi: np.ndarray) -> bool:
    J = pseudo_inertia(pi)
    return bool(np.linalg.eigvalsh(J)[0] > INTERIOR_RTOL * np.abs(J).max())


def _square_root(H: np.ndarray, g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """C with ``C^T C = H`` and ``c`` with ``C^T c = g``, for a positive semi-definite H.

    By eigen-decomposition (the barrier's Hessian of a light body spans many decades, where a
    Cholesky factorisation can fail on round-off); eigenvalues are floored at 1e-14 of the
    largest.
    """
    w, V = np.linalg.eigh(0.5 * (H + H.T))
    root = np.sqrt(np.maximum(w, 1e-14 * max(float(w.max()), 1e-300)))
    return root[:, None] * V.T, (V.T @ g) / root
