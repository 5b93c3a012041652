"""An honest uncertainty of the estimate: what the residual says, not what white noise would give.

The Laplace covariance of :func:`~mbctl.robots.identification.estimate.estimate` assumes the
torque residual is white noise of RMS sigma. On a log it is not: the low-pass filter, the
differenced accelerations, the smoothed Coulomb sign and the samples excluded around contacts
leave a residual that is systematic, correlated over many samples, and the Laplace standard
deviations are then far too small (tens of sigma from a known truth on noise-free logs).

Two residual-aware estimates of the covariance, and the larger per direction kept:

* **Segment jackknife**: the training samples are cut into :data:`SEGMENTS` contiguous time
  segments; the (unconstrained) MAP estimate is recomputed with each segment left out, and the
  delete-one jackknife covariance ``(G - 1) / G sum_g (theta_g - mean)(theta_g - mean)^T`` is
  the spread a different stretch of motion gives.
* **Newey-West (HAC) sandwich**: ``A^-1 (S / sigma^4) A^-1`` with ``A`` the Hessian of the MAP
  objective and ``S`` the Bartlett-weighted long-run covariance of the per-sample scores
  ``W_k^T r_k`` (``r_k`` the residual at the estimate), with a bandwidth of
  :data:`HAC_BANDWIDTH_S` of log time: the residual's autocorrelation counted, not assumed away.

Neither sees an error every segment shares: the low-pass filter's (a lag and an attenuation of
the accelerations, the same all along the log), which biases friction and inertia together. So
the fit is repeated at twice the cutoff (:func:`filter_term`): the filter's error falls about as
the square of the cutoff, so the error at the cutoff is about 4/3 of the change, and its outer
product is the systematic term ``C_filter``.

Nor the discretisation's: the acceleration is the forward difference of v over one log step,
and whether the plant's friction acted at the velocity at the start of the step or at its end
(MuJoCo's implicit integrators damp with the end's) is not in the log. The fit is repeated with
the velocities at the end of the step (``v + a dt``) and the outer product of the change is the
term ``C_step`` (:func:`shift_term`).

The reported covariance is ``C_laplace + max(C_jackknife, C_hac) + C_filter + C_step``, where the max of
the two is taken along the eigen-directions of their sum's whitened difference (a positive
semi-definite upper bound of both, so the standard deviation of any combination of parameters is
at least either estimate's). The Laplace term keeps the prior's uncertainty where the data are
silent.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from mbctl.robots.identification.estimate import Estimate
from mbctl.robots.identification.parameters import ParameterSet
from mbctl.robots.identification.regressor import LinearSystem, SampleEquations, _Accumulator
from mbctl.robots.identification.samples import Samples

#: Contiguous time segments of the jackknife.
SEGMENTS = 10
#: Bartlett bandwidth [s] of the Newey-West estimate (about a trajectory's slowest harmonic).
HAC_BANDWIDTH_S = 1.0


@dataclass(frozen=True)
class Uncertainty:
    """The residual-aware covariance of an estimate.

    Attributes:
        covariance: The reported covariance (n, n): Laplace plus the larger of the other two.
        laplace: The white-noise (Laplace) covariance (n, n).
        jackknife: The segment-jackknife covariance (n, n).
        hac: The Newey-West sandwich covariance (n, n).
        filter: The systematic term of the filter (n, n) (zeros: no filter, or no room to refit).
        step: The systematic term of the discretisation (n, n) (zeros: not computed).
        segments: Segments of the jackknife.
        bandwidth_samples: Bartlett bandwidth of the HAC estimate [samples].
    """

    covariance: np.ndarray
    laplace: np.ndarray
    jackknife: np.ndarray
    hac: np.ndarray
    filter: np.ndarray
    step: np.ndarray
    segments: int
    bandwidth_samples: int

    @property
    def std(self) -> np.ndarray:
        """Reported standard deviations (n,)."""
        return np.sqrt(np.maximum(np.diag(self.covariance), 0.0))


def upper_bound(C1: np.ndarray, C2: np.ndarray) -> np.ndarray:
    """A PSD matrix C with ``C >= C1`` and ``C >= C2`` (Loewner order), tight along shared axes.

    With ``T = (C1 + C2)^1/2`` (pseudo-inverse on its null space), ``T^-1 C1 T^-1 = V D V^T`` and
    ``T^-1 C2 T^-1 = V (I - D) V^T`` on the range: C is ``T V max(D, I - D) V^T T``.
    """
    S = 0.5 * ((C1 + C2) + (C1 + C2).T)
    w, U = np.linalg.eigh(S)
    keep = w > 1e-14 * max(float(w.max()), 1e-300)
    if not keep.any():
        return np.zeros_like(S)
    T = U[:, keep] * np.sqrt(w[keep])  # S = T T^T on its range
    Tp = U[:, keep] / np.sqrt(w[keep])  # T^+ columns
    D1 = Tp.T @ C1 @ Tp
    d, V = np.linalg.eigh(0.5 * (D1 + D1.T))
    m = np.maximum(d, 1.0 - d)
    X = T @ V
    return (X * m) @ X.T


def map_estimate(params: ParameterSet, system: LinearSystem, sigma: float) -> np.ndarray:
    """The unconstrained MAP estimate (n,) of ``system`` with torque noise ``sigma`` (the prior included)."""
    s = params.prior_std()
    B = params.prior_factor()
    Q, RA = np.linalg.qr(np.vstack([system.R / sigma, B]) * s)
    return scipy.linalg.lstsq(RA, Q.T @ np.concatenate([system.z / sigma, B @ params.nominal]))[0] * s


def filter_term(theta_cutoff: np.ndarray, theta_doubled: np.ndarray) -> np.ndarray:
    """Systematic covariance (n, n) of the filter from the estimates at the cutoff and at twice it.

    A filter error falling as the square of the cutoff: ``e(f) - e(2 f) = 3/4 e(f)``, so the error
    at the cutoff is ``4/3`` of the change; the term is its outer product (a fully correlated error).
    """
    d = (4.0 / 3.0) * (np.asarray(theta_doubled, dtype=float) - np.asarray(theta_cutoff, dtype=float))
    return np.outer(d, d)


def shift_term(theta: np.ndarray, theta_shifted: np.ndarray) -> np.ndarray:
    """Systematic covariance (n, n) of the discretisation.

    The outer product of the change of the fit when the velocities are taken at the end of each
    log step (``theta_shifted``) instead of its start (``theta``).
    """
    d = np.asarray(theta_shifted, dtype=float) - np.asarray(theta, dtype=float)
    return np.outer(d, d)


def bartlett_long_run(scores: np.ndarray, lags: int) -> np.ndarray:
    """Newey-West long-run covariance ``sum_l (1 - |l| / (L + 1)) Gamma_l`` (n, n) of ``scores`` (m, n).

    The Bartlett kernel is a box convolved with itself: with ``u_t`` the sum of the scores over the
    window ``[t - L, t]`` (zero-padded ends), the sum is ``sum_t u_t u_t^T / (L + 1)``, in O(m n^2)
    whatever the bandwidth.
    """
    m, n = scores.shape
    padded = np.vstack([np.zeros((lags + 1, n)), scores, np.zeros((lags, n))])
    c = np.cumsum(padded, axis=0)
    u = c[lags + 1:] - c[:-lags - 1]  # window sums, m + L of them
    return u.T @ u / (lags + 1)


def residual_uncertainty(params: ParameterSet, samples: Samples, contact: str, est: Estimate,
                         filter_cov: np.ndarray | None = None, step_cov: np.ndarray | None = None,
                         segments: int = SEGMENTS,
                         bandwidth_s: float = HAC_BANDWIDTH_S) -> Uncertainty:
    """The covariance of :mod:`this module <mbctl.robots.identification.uncertainty>`'s docstring.

    Args:
        params: The parameter set of the estimate.
        samples: The training samples it was fitted to, in time order (logs one after the other).
        contact: The contact mode of the fit ("projected" or "measured").
        est: The estimate (its theta, sigma and Laplace covariance).
        filter_cov: The filter's systematic term (:func:`filter_term`), or None.
        step_cov: The discretisation's systematic term (:func:`shift_term`), or None.
        segments: Contiguous segments of the jackknife (fewer when there are few samples).
        bandwidth_s: Bartlett bandwidth [s] of the HAC estimate.
    """
    n, m = params.n, len(samples)
    G = max(2, min(segments, m // 5))
    bounds = np.linspace(0, m, G + 1).astype(int)
    segment_of = np.searchsorted(bounds[1:], np.arange(m), side="right")
    accs = [_Accumulator(n) for _ in range(G)]
    scores = np.zeros((m, n))
    theta = est.theta
    for k, (W, y, P) in enumerate(SampleEquations(params, samples, contact)):
        if P is not None:
            W, y = P @ W, P @ y
        accs[segment_of[k]].add(W, y)
        scores[k] = W.T @ (y - W @ theta)
    systems = [a.system() for a in accs]
    sigma = est.sigma
    s = params.prior_std()
    B = params.prior_factor()
    prior_rows, prior_rhs = B * s, B @ params.nominal
    # jackknife: the unconstrained MAP without segment g, in the scaled coordinates u = theta / s
    fits = np.empty((G, n))
    for g in range(G):
        rows = np.vstack([*(sys.R for i, sys in enumerate(systems) if i != g)]) / sigma * s
        rhs = np.concatenate([sys.z for i, sys in enumerate(systems) if i != g]) / sigma
        Q, RA = np.linalg.qr(np.vstack([rows, prior_rows]))
        fits[g] = scipy.linalg.lstsq(RA, Q.T @ np.concatenate([rhs, prior_rhs]))[0] * s
    dev = fits - fits.mean(axis=0)
    jackknife = (G - 1) / G * dev.T @ dev
    # HAC sandwich: A^-1 S A^-1 / sigma^4, Bartlett weights over L lags
    dt = float(np.median(np.diff(samples.t_s))) if m > 1 else 1.0
    L = int(max(1, min(m - 1, round(bandwidth_s / max(dt, 1e-12)))))
    S = bartlett_long_run(scores, L)
    A_inv = est.covariance  # the Laplace covariance is the inverse Hessian of the MAP objective
    hac = A_inv @ S @ A_inv / sigma**4
    hac = 0.5 * (hac + hac.T)
    zero = np.zeros((n, n))
    filt = zero if filter_cov is None else filter_cov
    step = zero if step_cov is None else step_cov
    covariance = est.covariance + upper_bound(jackknife, hac) + filt + step
    return Uncertainty(0.5 * (covariance + covariance.T), est.covariance, jackknife, hac, filt, step, G, L)
