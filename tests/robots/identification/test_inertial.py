"""One body's parameters: conversions, frame changes, log-Cholesky, physical consistency."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given
from hypothesis import strategies as st

from mbctl.robots.identification.exceptions import InconsistentParameters
from mbctl.robots.identification.inertial import (
    consistency_problems,
    from_inertial,
    from_log_cholesky,
    pseudo_inertia,
    to_inertial,
    to_log_cholesky,
    transform_matrix,
)

finite = st.floats(-1.0, 1.0, allow_nan=False)


def _body(seed: int) -> pin.Inertia:
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((3, 3))
    moments = rng.uniform(0.5, 1.0, 3)  # any three in [0.5, 1] satisfy the triangle inequalities
    R = np.linalg.qr(A)[0]
    return pin.Inertia(float(rng.uniform(0.1, 5.0)), rng.standard_normal(3) * 0.2, R @ np.diag(moments) @ R.T)


@pytest.mark.parametrize("seed", range(5))
def test_parameters_are_pinocchios(seed):
    inertia = _body(seed)
    pi = from_inertial(inertia.mass, inertia.lever, inertia.inertia)
    np.testing.assert_allclose(pi, inertia.toDynamicParameters(), atol=1e-14)
    m, c, I_c = to_inertial(pi)
    np.testing.assert_allclose([m, *c], [inertia.mass, *inertia.lever], atol=1e-14)
    np.testing.assert_allclose(I_c, inertia.inertia, atol=1e-14)
    expected = pin.PseudoInertia.FromInertia(inertia).toMatrix()
    np.testing.assert_allclose(pseudo_inertia(pi), expected, atol=1e-14)


@given(st.integers(0, 1000), st.tuples(finite, finite, finite), st.tuples(finite, finite, finite))
def test_frame_change_matches_pinocchio_se3_act(seed, rpy, p):
    inertia = _body(seed)
    X_AB = pin.SE3(pin.rpy.rpyToMatrix(*rpy), np.array(p))
    expected = X_AB.act(inertia).toDynamicParameters()
    got = transform_matrix(X_AB) @ inertia.toDynamicParameters()
    np.testing.assert_allclose(got, expected, atol=1e-12)


@pytest.mark.parametrize("seed", range(5))
def test_log_cholesky_round_trip_and_jacobian(seed):
    pi = _body(seed).toDynamicParameters()
    xi = to_log_cholesky(pi)
    back, J = from_log_cholesky(xi)
    np.testing.assert_allclose(back, pi, rtol=1e-12, atol=1e-12)
    eps = 1e-7
    numeric = np.stack([(from_log_cholesky(xi + eps * e)[0] - back) / eps for e in np.eye(10)], axis=1)
    np.testing.assert_allclose(J, numeric, atol=1e-5)


@given(st.lists(st.floats(-3, 3, allow_nan=False), min_size=10, max_size=10))
def test_every_log_cholesky_vector_is_a_physical_body(xi):
    pi, _ = from_log_cholesky(np.array(xi))
    assert consistency_problems(pi) == []
    assert np.linalg.eigvalsh(pseudo_inertia(pi))[0] > 0


def test_unphysical_bodies_are_named():
    assert consistency_problems(from_inertial(-1.0, np.zeros(3), np.eye(3))) == ["mass -1 kg is not > 0"]
    bad = from_inertial(1.0, np.zeros(3), np.diag([0.1, 0.1, 0.3]))
    assert "triangle inequality violated: 0.1 + 0.1 < 0.3 kg m^2" in consistency_problems(bad)
    with pytest.raises(InconsistentParameters, match="not physically consistent"):
        to_log_cholesky(bad)
    point = from_inertial(2.0, np.array([0.1, 0, 0]), np.zeros((3, 3)))  # semi-definite: nudged inside
    np.testing.assert_allclose(from_log_cholesky(to_log_cholesky(point))[0], point, atol=1e-9)
