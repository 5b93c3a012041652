"""Hand-written scalar math for the small vectors of the control loop, in one place.

Why not numpy: every numpy call costs a fixed ~0.5-15 us of dispatch, array creation and
dtype checks, which dwarfs the arithmetic on a 3- or 4-vector. These helpers work on Python
floats (pass ``arr.tolist()``) and cost a fraction of that. Measured on the development machine
(Python 3.11, numpy 2.4; medians of ``timeit``):

====================================  ==========================  ===========================
operation                             numpy / Pinocchio           here (incl. ``tolist``)
====================================  ==========================  ===========================
cross product of two (3,) arrays      ``np.cross``: 13 us         ``cross3``: 0.5 us
finite check of a (12,) vector        ``np.isfinite().all()``:    ``all_finite``: 0.25 us
                                      1.1 us
``R_WB^T v`` from a quaternion        normalize, build R, ``@``:  ``quat_xyzw_rotate_inverse``:
                                      4.8 us (``pin.Quaternion``  0.6 us
                                      2.0 us)
====================================  ==========================  ===========================

The control loop runs these every cycle: ``bench/bench_control.py`` (G1 PD + gravity: the API
loop within 1.15x of a hand-written loop; 2-link computed torque within 1.5x) and
``bench/bench_sim.py`` (``Simulator.step`` within 1.15x of a raw ``mj_step`` on the G1) are the
budgets they keep. Each helper is tested against numpy and Pinocchio in
``tests/robots/test_fastmath.py``; change one only with that test and both benches.

Notation: quaternions are (x, y, z, w) as Pinocchio stores them (the toolkit's public
convention; MuJoCo stores (w, x, y, z)) and need not be unit: the rotation is that of the
normalized quaternion. ``R`` rotates frame-B vectors into frame W (``R_WB``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from mbctl.robots.exceptions import StateError

#: Up to this many entries the plain-Python checks below beat numpy; above, use numpy. Measured
#: crossovers: ``any_outside`` ~80 entries (0.25 us at 2, 1.8 us at 64, against numpy's flat
#: 2.2 us), ``all_finite`` ~110 (against 1.35 us). 64 covers a G1's 29 actuators and 36 q.
SMALL_VECTOR_MAX = 64

#: Indices that reorder a quaternion (w, x, y, z) into (x, y, z, w): ``q_xyzw = q_wxyz[idx]``.
XYZW_FROM_WXYZ = (1, 2, 3, 0)

#: Indices that reorder a quaternion (x, y, z, w) into (w, x, y, z): ``q_wxyz = q_xyzw[idx]``.
WXYZ_FROM_XYZW = (3, 0, 1, 2)


# ---------------------------------------------------------------------------------- checks
def all_finite(values: Sequence[float]) -> bool:
    """Whether every entry is finite (neither NaN nor +-inf).

    The sum of the floats is NaN or infinite iff an entry is, or iff finite entries overflow;
    only then are the entries checked one by one. ~5x cheaper than ``np.isfinite(x).all()`` on
    a vector of a dozen entries.

    Args:
        values: The entries, as Python floats (e.g. ``arr.tolist()``) for speed.

    Returns:
        True if every entry is finite (True for an empty sequence).
    """
    if math.isfinite(sum(values)):
        return True
    return all(map(math.isfinite, values))


def any_outside(values: Sequence[float], low: Sequence[float], high: Sequence[float]) -> bool:
    """Whether some ``values[i]`` lies outside ``[low[i], high[i]]``.

    Plain Python beats the four numpy calls of ``((v < lo) | (v > hi)).any()`` up to
    ``SMALL_VECTOR_MAX`` entries. A NaN value is never outside (it compares false), as in numpy.

    Args:
        values: The values (n,), as Python floats for speed.
        low: Lower bounds (n,) (``-inf`` where unbounded).
        high: Upper bounds (n,) (``+inf`` where unbounded).

    Returns:
        True if some value is below its lower or above its upper bound.
    """
    for v, lo, hi in zip(values, low, high):  # noqa: B905 (hot path; callers pass equal lengths)
        if v < lo or v > hi:
            return True
    return False


# ---------------------------------------------------------------------------------- vectors
def cross3(a: Sequence[float], b: Sequence[float]) -> tuple[float, float, float]:
    """The cross product ``a x b`` of two 3-vectors.

    Args:
        a: First vector (3,), any unit, any frame (both in the same frame).
        b: Second vector (3,), in the frame of ``a``.

    Returns:
        ``a x b`` (3,) in that frame, unit the product of the inputs' units.
    """
    a0, a1, a2 = a
    b0, b1, b2 = b
    return (a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0)


# ---------------------------------------------------------------------------------- quaternions
def _scale(x: float, y: float, z: float, w: float) -> float:
    """``2 / |q|^2``: the factor that makes the rotation formulas exact for non-unit q."""
    n2 = x * x + y * y + z * z + w * w
    if n2 == 0.0:
        raise StateError(
            f"quaternion (x, y, z, w) = ({x!r}, {y!r}, {z!r}, {w!r}) has zero norm; a rotation "
            "needs a non-zero quaternion (normally a unit one)"
        )
    return 2.0 / n2


def quat_xyzw_to_matrix(quat_xyzw: Sequence[float]) -> np.ndarray:
    """Rotation matrix ``R_WB`` (3, 3) of a quaternion (x, y, z, w), normalized first.

    Args:
        quat_xyzw: Orientation of frame B in frame W (4,), (x, y, z, w), non-zero.

    Returns:
        ``R_WB`` (3, 3), a new array; non-finite entries if the quaternion has any.

    Raises:
        StateError: A zero quaternion.
    """
    x, y, z, w = quat_xyzw
    s = _scale(x, y, z, w)
    return np.array(
        [
            [1.0 - s * (y * y + z * z), s * (x * y - z * w), s * (x * z + y * w)],
            [s * (x * y + z * w), 1.0 - s * (x * x + z * z), s * (y * z - x * w)],
            [s * (x * z - y * w), s * (y * z + x * w), 1.0 - s * (x * x + y * y)],
        ]
    )


def quat_xyzw_rotate(quat_xyzw: Sequence[float], vec_B: Sequence[float]) -> tuple[float, float, float]:
    """``R_WB vec_B``: a frame-B vector expressed in frame W.

    Args:
        quat_xyzw: Orientation of B in W (4,), (x, y, z, w), non-zero.
        vec_B: A vector (3,) in B, any unit.

    Returns:
        The vector (3,) in W, same unit.

    Raises:
        StateError: A zero quaternion.
    """
    x, y, z, w = quat_xyzw
    return _rotate(x, y, z, w, _scale(x, y, z, w), vec_B)


def _rotate(
    x: float, y: float, z: float, w: float, s: float, v: Sequence[float]
) -> tuple[float, float, float]:
    """R(q) v with s = 2 / |q|^2 (the conjugate q* = (-x, -y, -z, w) has the same s)."""
    vx, vy, vz = v
    return (
        (1.0 - s * (y * y + z * z)) * vx + s * (x * y - z * w) * vy + s * (x * z + y * w) * vz,
        s * (x * y + z * w) * vx + (1.0 - s * (x * x + z * z)) * vy + s * (y * z - x * w) * vz,
        s * (x * z - y * w) * vx + s * (y * z + x * w) * vy + (1.0 - s * (x * x + y * y)) * vz,
    )


def quat_xyzw_rotate_inverse(
    quat_xyzw: Sequence[float], vec_W: Sequence[float]
) -> tuple[float, float, float]:
    """``R_WB^T vec_W``: a frame-W vector expressed in frame B.

    Args:
        quat_xyzw: Orientation of B in W (4,), (x, y, z, w), non-zero.
        vec_W: A vector (3,) in W, any unit.

    Returns:
        The vector (3,) in B, same unit.

    Raises:
        StateError: A zero quaternion.
    """
    x, y, z, w = quat_xyzw
    return _rotate(-x, -y, -z, w, _scale(x, y, z, w), vec_W)  # the conjugate rotates by R_WB^T
