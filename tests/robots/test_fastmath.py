"""The hand-written small-vector helpers (robots/fastmath.py) against numpy and Pinocchio.

Where the helper does the same IEEE operations as numpy (the cross product), the results must be
bit-identical, NaN and inf included; where the order of operations differs (rotations), they
agree to a few ulp and non-finite inputs stay non-finite.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from mbctl.robots import StateError
from mbctl.robots.fastmath import (
    SMALL_VECTOR_MAX,
    WXYZ_FROM_XYZW,
    XYZW_FROM_WXYZ,
    all_finite,
    any_outside,
    cross3,
    quat_xyzw_rotate,
    quat_xyzw_rotate_inverse,
    quat_xyzw_to_matrix,
)

#: Every float64, NaN and +-inf included.
any_float = st.floats(allow_nan=True, allow_infinity=True)
moderate = st.floats(-1e3, 1e3)
vec3 = arrays(float, 3, elements=moderate)
#: Quaternions far from zero, of any norm in about [0.05, 20] (the helpers normalize).
quat = arrays(float, 4, elements=st.floats(-10.0, 10.0)).filter(lambda q: np.linalg.norm(q) > 0.05)
#: Entries with at least one NaN or inf.
with_nonfinite = st.sampled_from([np.nan, np.inf, -np.inf])


def pin_rotation(q_xyzw: np.ndarray) -> np.ndarray:
    """R_WB from Pinocchio's (Eigen's) quaternion, normalized: the independent reference."""
    x, y, z, w = q_xyzw
    return pin.Quaternion(w, x, y, z).normalized().toRotationMatrix()


# ------------------------------------------------------------------------------ checks
@given(st.lists(any_float, max_size=2 * SMALL_VECTOR_MAX))
def test_all_finite_matches_numpy(values):
    assert all_finite(values) is bool(np.all(np.isfinite(np.array(values, dtype=float))))


@pytest.mark.parametrize(
    "values, expected",
    [
        ([], True),
        ([1e308, 1e308], True),  # the sum overflows to inf: the exact check must say finite
        ([1e308, 1e308, -1e308, -1e308], True),
        ([-1e308, -1e308, 5.0], True),
        ([1e308, 1e308, -np.inf], False),
        ([0.0, np.nan], False),
        ([np.inf, -np.inf], False),  # the sum is NaN
        ([-np.inf], False),
    ],
)
def test_all_finite_edge_cases(values, expected):
    assert all_finite(values) is expected
    assert all_finite(np.array(values, dtype=float).tolist()) is expected


@given(
    st.integers(0, SMALL_VECTOR_MAX).flatmap(
        lambda n: st.tuples(*(arrays(float, n, elements=any_float) for _ in range(3)))
    )
)
def test_any_outside_matches_numpy(vlh):
    values, low, high = vlh
    expected = bool(np.any((values < low) | (values > high)))
    assert any_outside(values.tolist(), low.tolist(), high.tolist()) is expected


def test_any_outside_cases():
    low, high = [-1.0, -np.inf], [1.0, 2.0]
    assert not any_outside([1.0, -1e300], low, high)  # bounds are inclusive; -inf unbounded
    assert any_outside([1.0 + 2e-16, 0.0], low, high)
    assert any_outside([0.0, 2.5], low, high)
    assert not any_outside([np.nan, np.nan], low, high)  # NaN compares false, as in numpy


# ------------------------------------------------------------------------------ cross product
@given(arrays(float, 3, elements=any_float), arrays(float, 3, elements=any_float))
def test_cross3_is_bit_identical_to_numpy(a, b):
    got = np.array(cross3(a.tolist(), b.tolist()))
    with np.errstate(invalid="ignore", over="ignore"):
        want = np.cross(a, b)
    np.testing.assert_array_equal(got, want)  # NaN == NaN here; inf signs must match


@given(vec3, vec3)
def test_cross3_properties(a, b):
    c = np.array(cross3(a.tolist(), b.tolist()))
    np.testing.assert_array_equal(c, -np.array(cross3(b.tolist(), a.tolist())))
    scale = max(1.0, float(np.linalg.norm(a) * np.linalg.norm(b)))
    # orthogonal to both factors (the dot is a difference of products of size |a|^2 |b|)
    assert abs(c @ a) <= 1e-12 * scale * max(1.0, float(np.linalg.norm(a)))
    assert abs(c @ b) <= 1e-12 * scale * max(1.0, float(np.linalg.norm(b)))
    # |a x b|^2 = |a|^2 |b|^2 - (a.b)^2 (Lagrange)
    lagrange = (a @ a) * (b @ b) - (a @ b) ** 2
    assert c @ c == pytest.approx(lagrange, abs=1e-9 * scale**2)


def test_cross3_of_the_basis():
    assert cross3([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]) == (0.0, 0.0, 1.0)
    assert cross3([0.0, 0.0, 1.0], [1.0, 0.0, 0.0]) == (0.0, 1.0, 0.0)


# ------------------------------------------------------------------------------ quaternions
def test_reorder_indices_match_pinocchio():
    q_wxyz = np.array([0.9, 0.1, -0.3, 0.2])
    q_xyzw = q_wxyz[list(XYZW_FROM_WXYZ)]
    np.testing.assert_array_equal(q_xyzw, pin.Quaternion(*q_wxyz).coeffs())  # coeffs: x, y, z, w
    np.testing.assert_array_equal(q_xyzw[list(WXYZ_FROM_XYZW)], q_wxyz)


@settings(deadline=None)
@given(quat)
def test_matrix_matches_pinocchio(q):
    R = quat_xyzw_to_matrix(q.tolist())
    np.testing.assert_allclose(R, pin_rotation(q), rtol=0, atol=4e-15)
    np.testing.assert_allclose(R @ R.T, np.eye(3), rtol=0, atol=4e-15)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-14)


@settings(deadline=None)
@given(quat, vec3)
def test_rotate_and_inverse_match_pinocchio(q, v):
    R = pin_rotation(q)
    tol = 4e-15 * max(1.0, float(np.linalg.norm(v)))
    np.testing.assert_allclose(quat_xyzw_rotate(q.tolist(), v.tolist()), R @ v, rtol=0, atol=tol)
    np.testing.assert_allclose(quat_xyzw_rotate_inverse(q.tolist(), v.tolist()), R.T @ v,
                               rtol=0, atol=tol)
    back = quat_xyzw_rotate_inverse(q.tolist(), quat_xyzw_rotate(q.tolist(), v.tolist()))
    np.testing.assert_allclose(back, v, rtol=0, atol=2 * tol)


def test_rotate_a_quarter_turn_about_z():
    s = np.sqrt(0.5)
    np.testing.assert_allclose(quat_xyzw_rotate([0.0, 0.0, s, s], [1.0, 0.0, 0.0]), [0.0, 1.0, 0.0],
                               atol=1e-16)
    np.testing.assert_allclose(quat_xyzw_rotate_inverse([0.0, 0.0, s, s], [1.0, 0.0, 0.0]),
                               [0.0, -1.0, 0.0], atol=1e-16)
    # a non-unit quaternion rotates like its normalized self
    np.testing.assert_allclose(quat_xyzw_rotate([0.0, 0.0, 3.0, 3.0], [1.0, 0.0, 0.0]),
                               [0.0, 1.0, 0.0], atol=1e-15)


@given(quat, vec3, st.integers(0, 2), with_nonfinite)
def test_nonfinite_vector_reaches_every_component_like_numpy(q, v, i, bad):
    v = v.copy()
    v[i] = bad
    R = pin_rotation(q)
    with np.errstate(invalid="ignore"):
        want, want_inv = R @ v, R.T @ v
    assert not np.any(np.isfinite(want)) and not np.any(np.isfinite(want_inv))
    assert not np.any(np.isfinite(quat_xyzw_rotate(q.tolist(), v.tolist())))
    assert not np.any(np.isfinite(quat_xyzw_rotate_inverse(q.tolist(), v.tolist())))


@given(quat, vec3, st.integers(0, 3), with_nonfinite)
def test_nonfinite_quaternion_never_gives_a_finite_rotation(q, v, i, bad):
    q = q.copy()
    q[i] = bad
    assert not np.all(np.isfinite(quat_xyzw_to_matrix(q.tolist())))
    assert not np.all(np.isfinite(quat_xyzw_rotate(q.tolist(), v.tolist())))
    assert not np.all(np.isfinite(quat_xyzw_rotate_inverse(q.tolist(), v.tolist())))


@pytest.mark.parametrize("fn", [
    lambda q: quat_xyzw_to_matrix(q),
    lambda q: quat_xyzw_rotate(q, [1.0, 2.0, 3.0]),
    lambda q: quat_xyzw_rotate_inverse(q, [1.0, 2.0, 3.0]),
])
def test_zero_quaternion_is_a_state_error(fn):
    with pytest.raises(StateError, match=r"quaternion \(x, y, z, w\) = \(0.0, 0.0, 0.0, 0.0\) has "
                                         "zero norm"):
        fn([0.0, 0.0, 0.0, 0.0])
