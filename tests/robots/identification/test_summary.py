"""The report's numbers: the CoM's standard deviation by the delta method against Monte Carlo."""

from __future__ import annotations

import numpy as np
import pytest

from mbctl.robots.identification import IdentificationError
from mbctl.robots.identification.inertial import from_inertial
from mbctl.robots.identification.summary import com_covariance, com_std

#: A 2 kg body, CoM off its origin (mostly along z, like a torso payload) [kg, m, kg m^2].
MASS_KG = 2.0
COM_M = np.array([0.05, -0.02, 0.25])
INERTIA_COM = np.diag([0.02, 0.03, 0.015])


def _covariance(std_m_kg: float, std_h_kg_m: float, correlation: float) -> np.ndarray:
    """A (10, 10) covariance of (m, h, I): mass and first moments correlated, inertia independent."""
    std = np.array([std_m_kg, std_h_kg_m, std_h_kg_m, std_h_kg_m, *([1e-4] * 6)])
    corr = np.eye(10)
    corr[0, 1:4] = corr[1:4, 0] = correlation  # m with each h_i
    corr[1, 3] = corr[3, 1] = 0.3  # h_x with h_z
    return corr * np.outer(std, std)


def _monte_carlo(pi: np.ndarray, cov: np.ndarray, n: int, seed: int) -> np.ndarray:
    """Sample covariance (3, 3) of c = h / m over n draws of pi ~ N(pi, cov)."""
    draws = np.random.default_rng(seed).multivariate_normal(pi, cov, size=n)
    c = draws[:, 1:4] / draws[:, :1]
    return np.cov(c, rowvar=False)


@pytest.mark.parametrize(("std_m_kg", "std_h_kg_m", "correlation"), [
    (0.02, 0.002, 0.0),    # both terms of J_c, independent
    (0.02, 0.002, 0.6),    # mass and first moments correlated: the cross terms count
    (0.04, 1e-5, 0.0),     # the mass dominates: std(c) ~ |c| std(m) / m
])
def test_delta_method_com_std_matches_monte_carlo(std_m_kg, std_h_kg_m, correlation):
    pi = from_inertial(MASS_KG, COM_M, INERTIA_COM)
    cov = _covariance(std_m_kg, std_h_kg_m, correlation)
    mc = _monte_carlo(pi, cov, n=400_000, seed=7)
    # Monte Carlo's relative error on a std is ~1/sqrt(2n) ~ 0.1 %; the delta method's bias is second
    # order in std(m)/m (<= 2 %, so <= 0.04 %): both well inside 1 %
    np.testing.assert_allclose(com_std(pi, cov), np.sqrt(np.diag(mc)), rtol=1e-2)
    np.testing.assert_allclose(com_covariance(pi, cov), mc, rtol=3e-2, atol=1e-3 * np.abs(mc).max())


def test_the_mass_term_is_not_left_out():
    """With exact first moments the CoM's spread comes from the mass alone: |c| std(m) / m per axis."""
    pi = from_inertial(MASS_KG, COM_M, INERTIA_COM)
    cov = _covariance(0.04, 1e-12, 0.0)
    np.testing.assert_allclose(com_std(pi, cov), np.abs(COM_M) * 0.04 / MASS_KG, rtol=1e-6)


def test_a_body_without_mass_has_no_com():
    pi = from_inertial(MASS_KG, COM_M, INERTIA_COM)
    pi[0] = 0.0
    with pytest.raises(IdentificationError, match="positive mass"):
        com_std(pi, np.eye(10))
    with pytest.raises(IdentificationError, match=r"pi \(10,\) and covariance \(10, 10\)"):
        com_std(np.ones(9), np.eye(10))
