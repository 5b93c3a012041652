"""Every-cycle figures of the jobs' bounded logs: extremes, the CoM tracking error and quantiles.

A long run keeps its plots' rows decimated (:func:`mbctl.control.loop.log_stride`); its figures
stay over every cycle: extremes and sums updated each cycle in plain floats (a few float operations,
no numpy store) or a batch of cycles at a time as arrays, and the medians and percentiles from every
cycle's value kept as float32.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

#: A point or vector (x, y, z) as plain floats [m].
Vec3 = tuple[float, float, float]


class CoMErrorSums:
    """The CoM tracking error summed cycle by cycle (:func:`mbctl.jobs.wbc_log.com_tracking_error`'s).

    Each cycle gives the reference at the state's time ``t`` and the plant's CoM at its time
    ``t_plant`` (no earlier than ``t``; later behind a link's latency). A plant sample waits until a
    reference time reaches its ``t_plant`` and is compared with the reference interpolated there
    (``np.interp``'s formula, held at the first reference before it); the samples after the last
    reference time are left out, as there. So the sums are that function's over every cycle so
    far, kept in a few floats (and the samples waiting: the latency's cycles).

    Attributes:
        count: Plant samples compared.
        sum_sq: Sum of their squared errors [m^2].
        last: The last one compared: its plant time [s] and error norm [m] (NaN before one).
        unordered: A plant sample came before a reference time already passed (a plant behind
            the controller's state, which no plant here is): the sums are then not the error's.
    """

    def __init__(self) -> None:
        self.count, self.sum_sq = 0, 0.0
        self.last = (math.nan, math.nan)
        self.unordered = False
        self._pending: deque[tuple[float, Vec3]] = deque()
        self._first: tuple[float, Vec3] | None = None  # (t, ref) of the first cycle
        self._prev: tuple[float, Vec3] | None = None  # (t, ref) of the cycle before

    def add(self, t: float, ref: Vec3, t_plant: float, com: Vec3) -> None:
        """One cycle: the reference (3,) [m] at ``t`` [s] and the plant's CoM (3,) [m] at ``t_plant`` [s]."""
        pending = self._pending
        if self._first is None:
            self._first = (t, ref)
        first = self._first
        if t_plant == t and not pending:  # no latency: this cycle's own reference
            self._compare(t_plant, com, ref)
        else:
            pending.append((t_plant, com))
            while pending and pending[0][0] <= t:
                tp, c = pending.popleft()
                self._compare(tp, c, self._reference_at(tp, t, ref, first))
        self._prev = (t, ref)

    def add_block(self, t: np.ndarray, ref: np.ndarray, t_plant: np.ndarray, com: np.ndarray) -> np.ndarray:
        """:meth:`add` for b cycles in order: times (b,) [s], references and CoMs (b, 3) [m].

        Returns:
            After each cycle, :attr:`last` (b, 2): the last sample compared, its time [s] and error [m].
        """
        b = len(t)
        if not b:
            return np.empty((0, 2))
        if self._pending or not np.array_equal(t_plant, t):  # behind a latency: cycle by cycle
            out = np.empty((b, 2))
            for i, (ti, ri, tpi, ci) in enumerate(zip(t.tolist(), ref.tolist(), t_plant.tolist(),
                                                      com.tolist(), strict=True)):
                self.add(ti, ri, tpi, ci)
                out[i] = self.last
            return out
        # no latency: each cycle's plant sample against its own reference
        if self._first is None:
            self._first = (float(t[0]), tuple(ref[0].tolist()))  # type: ignore[assignment]
        sq = np.sum((com - ref) ** 2, axis=1)
        e = np.sqrt(sq)
        self.count += b
        self.sum_sq += float(sq.sum())
        self.last = (float(t[-1]), float(e[-1]))
        self._prev = (float(t[-1]), tuple(ref[-1].tolist()))  # type: ignore[assignment]
        return np.column_stack((t, e))

    def _reference_at(self, tp: float, t: float, ref: Vec3, first: tuple[float, Vec3]) -> Vec3:
        """The reference at ``tp`` <= ``t`` (the newest reference time; ``first``: the first) as np.interp."""
        prev = self._prev
        if tp == t:
            return ref
        if tp < first[0]:
            return first[1]
        if prev is None or tp < prev[0]:
            self.unordered = True
            return ref
        t0, (x0, y0, z0) = prev
        if tp == t0:
            return prev[1]
        dt = t - t0
        x1, y1, z1 = ref
        return ((x1 - x0) / dt * (tp - t0) + x0, (y1 - y0) / dt * (tp - t0) + y0,
                (z1 - z0) / dt * (tp - t0) + z0)

    def _compare(self, tp: float, com: Vec3, ref: Vec3) -> None:
        """Sum one plant sample's error (its time ``tp`` [s], CoM and reference [m])."""
        ex, ey, ez = com[0] - ref[0], com[1] - ref[1], com[2] - ref[2]
        sq = ex * ex + ey * ey + ez * ez
        self.count += 1
        self.sum_sq += sq
        self.last = (tp, math.sqrt(sq))

    def rms(self) -> float:
        """RMS of the error norm [m] over the samples compared (NaN for none, or if unordered)."""
        return math.sqrt(self.sum_sq / self.count) if self.count and not self.unordered else math.nan


def nan_max(m: float, x: float) -> float:
    """The larger of ``m`` and ``x``, NaN once either is (as ``np.max``)."""
    return x if x > m or x != x else m


def nan_min(m: float, x: float) -> float:
    """The smaller of ``m`` and ``x``, NaN once either is (as ``np.min``)."""
    return x if x < m or x != x else m


def quantile(x: np.ndarray, how: str = "median") -> float:
    """Median, 95th percentile or largest value of ``x`` (NaN for no samples)."""
    if not x.size:
        return float("nan")
    return float(np.percentile(x, {"median": 50, "p95": 95, "max": 100}[how]))


def rows_note(stride: int, cycles: int) -> str:
    """A title's note that the curves show every ``stride``-th cycle ("" when they show every cycle)."""
    if stride == 1:
        return ""
    return f"\ncurves: every {stride}th of {cycles:,} cycles (the job's log); figures: every cycle"
