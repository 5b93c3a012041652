"""Cartesian paths: a line, a circle, a polyline (a square), parameterised by arc length.

Notation: a path is a curve ``p(s)`` (3,) [m] in the world frame W, parameterised by arc length
``s`` in ``0..L`` [m], with unit tangent ``t(s) = dp/ds`` and curvature vector
``k(s) = d2p/ds2`` [1/m]. Corners (where the tangent jumps) are listed by each path, so a timing
law (:func:`mbctl.planners.cartesian.time_path`) can come to rest at them.
"""

from __future__ import annotations

import abc
import math

import numpy as np
import numpy.typing as npt

from mbctl.planners.exceptions import InvalidPath


class CartesianPath(abc.ABC):
    """Base class of arc-length parameterised paths ``p(s)``, s in 0..length [m].

    Subclasses implement ``length``, ``corners`` and the vectorised ``_evaluate``.
    """

    @property
    @abc.abstractmethod
    def length(self) -> float:
        """Total arc length L [m]."""

    @property
    def corners(self) -> tuple[float, ...]:
        """Arc lengths [m] where the timing law must stop: 0, each sharp corner, and L."""
        return (0.0, self.length)

    @abc.abstractmethod
    def _evaluate(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, tangent and curvature vector (N, 3) each at valid arc lengths ``s`` (N,)."""

    def evaluate(self, s: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, unit tangent and curvature vector at arc lengths ``s``.

        Args:
            s: Arc lengths (N,) [m] in 0..length (a scalar gives (3,) outputs).

        Returns:
            ``p`` (N, 3) [m], ``t = dp/ds`` (N, 3) [-], ``k = d2p/ds2`` (N, 3) [1/m]. At a sharp
            corner the tangent and curvature of the following section are returned.

        Raises:
            InvalidPath: An ``s`` outside ``0..length`` (beyond a 1e-12 relative tolerance).
        """
        arr = np.asarray(s, dtype=float)
        scalar = arr.ndim == 0
        arr = np.atleast_1d(arr)
        tol = 1e-12 * max(1.0, self.length)
        if np.any(~np.isfinite(arr)) or np.any(arr < -tol) or np.any(arr > self.length + tol):
            bad = arr[~((arr >= -tol) & (arr <= self.length + tol))][0]
            raise InvalidPath(f"path parameter s = {float(bad)!r} m is outside 0..{self.length!r} m")
        p, t, k = self._evaluate(np.clip(arr, 0.0, self.length))
        if scalar:
            return p[0], t[0], k[0]
        return p, t, k

    def position(self, s: npt.ArrayLike) -> np.ndarray:
        """Position ``p(s)`` (N, 3) or (3,) [m] in W (see ``evaluate``)."""
        return self.evaluate(s)[0]

    def tangent(self, s: npt.ArrayLike) -> np.ndarray:
        """Unit tangent ``dp/ds`` (N, 3) or (3,) [-] (see ``evaluate``)."""
        return self.evaluate(s)[1]


class PolylinePath(CartesianPath):
    """Straight segments through vertices, with a sharp corner at each interior vertex.

    Args:
        vertices: Points (K, 3) [m] in W, K >= 2, consecutive points distinct.

    Raises:
        InvalidPath: Wrong shape, non-finite entries or a zero-length segment.
    """

    def __init__(self, vertices: npt.ArrayLike):
        v = np.array(vertices, dtype=float)
        if v.ndim != 2 or v.shape[1] != 3 or v.shape[0] < 2:
            raise InvalidPath(f"vertices must have shape (K, 3) with K >= 2; got {v.shape}")
        if not np.all(np.isfinite(v)):
            raise InvalidPath("vertices must be finite [m]")
        seg = np.diff(v, axis=0)
        lengths = np.linalg.norm(seg, axis=1)
        scale = max(1.0, float(np.max(np.abs(v))))
        short = np.flatnonzero(lengths <= 1e-12 * scale)
        if short.size:
            i = int(short[0])
            raise InvalidPath(
                f"segment {i} from vertex {i} to {i + 1} has length {float(lengths[i])!r} m; remove "
                "repeated vertices"
            )
        v.setflags(write=False)
        self._vertices = v
        self._directions = seg / lengths[:, None]
        self._s = np.concatenate([[0.0], np.cumsum(lengths)])

    @property
    def vertices(self) -> np.ndarray:
        """Vertices (K, 3) [m] (read-only)."""
        return self._vertices

    @property
    def length(self) -> float:
        """Total arc length [m]."""
        return float(self._s[-1])

    @property
    def corners(self) -> tuple[float, ...]:
        """Arc lengths of every vertex [m]; the timing law stops at each.

        It also stops at collinear interior vertices; merge those if it should not.
        """
        return tuple(float(x) for x in self._s)

    def _evaluate(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        i = np.clip(np.searchsorted(self._s, s, side="right") - 1, 0, len(self._directions) - 1)
        d = self._directions[i]
        p = self._vertices[i] + d * (s - self._s[i])[:, None]
        # Snap exact vertex parameters to the stored vertex (no round-off at corners).
        at_vertex = np.isin(s, self._s)
        if np.any(at_vertex):
            p[at_vertex] = self._vertices[np.searchsorted(self._s, s[at_vertex])]
        return p, d.copy(), np.zeros_like(p)


class LinePath(PolylinePath):
    """The straight segment from ``start`` to ``end`` (3,) [m]."""

    def __init__(self, start: npt.ArrayLike, end: npt.ArrayLike):
        super().__init__(np.vstack([_point("start", start), _point("end", end)]))


class CirclePath(CartesianPath):
    """A circular arc about ``center`` in the plane with unit normal ``normal``.

    ``p(s) = c + r (cos(s/r) u + sin(s/r) w)``, with ``u`` the start direction (projected into
    the plane and normalised) and ``w = n x u``; positive sweep turns counter-clockwise about n.

    Args:
        center: Circle centre (3,) [m] in W.
        radius: Radius r [m], > 0.
        normal: Plane normal (3,) [-] (normalised here).
        start_direction: Direction (3,) from the centre to the start point.
        sweep_rad: Swept angle [rad], non-zero (2 pi: a full circle; negative: clockwise).

    Raises:
        InvalidPath: Non-positive radius, zero sweep, a zero normal, or ``start_direction``
            parallel to ``normal``.
    """

    def __init__(
        self,
        center: npt.ArrayLike,
        radius: float,
        normal: npt.ArrayLike = (0.0, 0.0, 1.0),
        start_direction: npt.ArrayLike = (1.0, 0.0, 0.0),
        sweep_rad: float = 2.0 * math.pi,
    ):
        self.center = _point("center", center)
        self.center.setflags(write=False)
        if not (math.isfinite(radius) and radius > 0.0):
            raise InvalidPath(f"radius = {radius!r} m must be finite and > 0")
        if not (math.isfinite(sweep_rad) and sweep_rad != 0.0):
            raise InvalidPath(f"sweep_rad = {sweep_rad!r} rad must be finite and non-zero")
        self.radius = float(radius)
        self.sweep_rad = float(sweep_rad)
        self._n, self._u, self._w = _plane_basis(normal, start_direction)

    @property
    def normal(self) -> np.ndarray:
        """Unit plane normal (3,) [-]."""
        return self._n.copy()

    @property
    def length(self) -> float:
        """Arc length ``r |sweep|`` [m]."""
        return self.radius * abs(self.sweep_rad)

    def _evaluate(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        sign = math.copysign(1.0, self.sweep_rad)
        theta = sign * s / self.radius
        c, sn = np.cos(theta)[:, None], np.sin(theta)[:, None]
        radial = c * self._u + sn * self._w
        p = self.center + self.radius * radial
        t = sign * (-sn * self._u + c * self._w)
        k = -radial / self.radius
        return p, t, k


def square_path(
    center: npt.ArrayLike,
    side_length: float,
    normal: npt.ArrayLike = (0.0, 0.0, 1.0),
    edge_direction: npt.ArrayLike = (1.0, 0.0, 0.0),
) -> PolylinePath:
    """A closed square with sharp corners, traversed counter-clockwise about ``normal``.

    It starts and ends at the corner ``c - (d/2) u - (d/2) w`` and runs first along ``u`` (the
    edge direction projected into the plane), with ``w = n x u`` and d the side length.

    Args:
        center: Square centre (3,) [m] in W.
        side_length: Side length d [m], > 0.
        normal: Plane normal (3,) [-].
        edge_direction: Direction (3,) of the first edge.

    Returns:
        A 5-vertex polyline (the first vertex repeated at the end); its corners are at
        s = 0, d, 2d, 3d, 4d.

    Raises:
        InvalidPath: Non-positive side length, zero normal, or ``edge_direction`` parallel to
            ``normal``.
    """
    c = _point("center", center)
    if not (math.isfinite(side_length) and side_length > 0.0):
        raise InvalidPath(f"side_length = {side_length!r} m must be finite and > 0")
    _, u, w = _plane_basis(normal, edge_direction)
    h = 0.5 * float(side_length)
    corners = [c - h * u - h * w, c + h * u - h * w, c + h * u + h * w, c - h * u + h * w]
    return PolylinePath(np.vstack(corners + [corners[0]]))



def _point(label: str, value: npt.ArrayLike) -> np.ndarray:
    arr = np.array(value, dtype=float)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise InvalidPath(f"{label} must be a finite 3-D point [m]; got {value!r}")
    return arr


def _plane_basis(
    normal: npt.ArrayLike, start_direction: npt.ArrayLike
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    n = np.array(normal, dtype=float)
    d = np.array(start_direction, dtype=float)
    if n.shape != (3,) or not np.all(np.isfinite(n)) or np.linalg.norm(n) < 1e-12:
        raise InvalidPath(f"normal must be a finite non-zero 3-vector; got {normal!r}")
    if d.shape != (3,) or not np.all(np.isfinite(d)):
        raise InvalidPath(f"start direction must be a finite 3-vector; got {start_direction!r}")
    n = n / np.linalg.norm(n)
    u = d - (d @ n) * n
    if np.linalg.norm(u) < 1e-9 * max(1.0, float(np.linalg.norm(d))):
        raise InvalidPath(
            f"start direction {d.tolist()} is parallel to the normal {n.tolist()}; give a "
            "direction in the plane"
        )
    u = u / np.linalg.norm(u)
    w = np.cross(n, u)
    for arr in (n, u, w):
        arr.setflags(write=False)
    return n, u, w
