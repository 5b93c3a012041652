"""What a control run logs: bounded rows, every cycle's times and per-column sums (:class:`RunLog`).

Memory is bounded: a :class:`RunLog` keeps at most ``MAX_LOG_ROWS`` rows of q, v, command and
reference (every ``stride``-th cycle and the last of a longer run), its times and ticks every cycle
(16 bytes a cycle), and :class:`RunStats` sums every cycle, so a figure over the whole run (an RMS,
a largest deviation) stays exact however long the run.

:class:`LogWriter` fills one during :func:`mbctl.control.loop.run`: each cycle it copies the
cycle's q, v, command and reference into small staging arrays (a few row stores, while they are
still in the CPU's caches) and writes those into the kept rows and the sums :data:`LOG_BATCH` cycles
at a time, one numpy call per field. Keeping the cycle's objects instead and reading them back per
batch read them cold (about 1 ms a 256-cycle batch on a 29-joint humanoid against 0.3 ms now).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mbctl.control.exceptions import ControlError
from mbctl.robots.commands import Command
from mbctl.robots.interface import RobotState

#: Rows of q, v, command and reference a RunLog keeps at most (the G1: about 1.3 kB a row, 0.13 GB):
#: a longer run keeps every ``stride``-th cycle and its last (the same bound as the replay's samples,
#: ``mbctl.sim.recorder.MAX_REPLAY_SAMPLES``). Its times, ticks and :class:`RunStats` cover every cycle.
MAX_LOG_ROWS = 100_000
#: Cycles staged before :class:`LogWriter` writes them into the log's rows and sums.
LOG_BATCH = 64


@dataclass(frozen=True)
class ColumnStats:
    """Per-column extremes and sums of a quantity over every cycle of a run.

    Attributes:
        count: Cycles summed.
        min: Smallest value of each column (n,).
        max: Largest value of each column (n,).
        sum: Sum of each column (n,).
        sum_sq: Sum of the squares of each column (n,).
    """

    count: int
    min: np.ndarray
    max: np.ndarray
    sum: np.ndarray
    sum_sq: np.ndarray

    def max_abs(self, center: np.ndarray | float = 0.0) -> np.ndarray:
        """Largest ``|x - center|`` of each column (n,) (``center`` (n,) or a scalar)."""
        return np.maximum(self.max - center, center - self.min)

    def rms(self) -> np.ndarray:
        """Root mean square of each column (n,)."""
        return np.sqrt(self.sum_sq / self.count)

    def rms_all(self) -> float:
        """Root mean square over every entry of every cycle."""
        return float(np.sqrt(self.sum_sq.sum() / (self.count * self.sum_sq.size)))


@dataclass(frozen=True)
class RunStats:
    """Exact figures of every cycle of a run, whatever rows its log kept.

    Attributes:
        q: Measured configurations (nq columns).
        v: Measured velocities (nv columns).
        command: Command values sent (m columns).
        error: Joint tracking error ``q_ref - q`` [rad] in the controller's joint order, for a
            JointReference and a controller with a ``joint_map``; else None.
    """

    q: ColumnStats
    v: ColumnStats
    command: ColumnStats
    error: ColumnStats | None


@dataclass(frozen=True)
class RunLog:
    """What one run measured (the state before each cycle's command).

    The times and ticks cover every cycle. The rows (q, v, command, reference) are every cycle of
    a run of at most ``MAX_LOG_ROWS`` cycles (``stride`` 1); a longer one keeps every
    ``stride``-th cycle and the last, ``cycle`` naming each row's cycle. Figures over the whole run
    come from ``stats``, which sums every cycle.

    Attributes:
        t_s: Every cycle's time (N,) [s] since the interface's clock started.
        q: Measured configurations (R, nq), Pinocchio convention.
        v: Measured velocities (R, nv).
        command: Command values sent (R, m) ([N m] for torques, [rad] for position targets).
        reference: Reference positions (R, k): joint q_ref [rad] or task p_ref [m].
        reference_v: Reference velocities (R, k).
        wall_time_s: Wall-clock time of the loop [s].
        tick: The plant's tick of every cycle's state (N,) (``RobotState.tick``: aligns the run
            with the plant's own logs, e.g. a bridge's truth log).
        cycle: The cycle of each row (R,) (empty: every cycle, rows = cycles).
        stride: Cycles between kept rows (1: every cycle kept).
        stats: Sums over every cycle (None for a log made by hand, or by ``run(rows=False)``).
    """

    t_s: np.ndarray
    q: np.ndarray
    v: np.ndarray
    command: np.ndarray
    reference: np.ndarray
    reference_v: np.ndarray
    wall_time_s: float
    tick: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.int64))
    cycle: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.int64))
    stride: int = 1
    stats: RunStats | None = None

    def __post_init__(self) -> None:
        if self.cycle.size == 0 and len(self.q):
            object.__setattr__(self, "cycle", np.arange(len(self.q)))

    @property
    def cycles(self) -> int:
        """Number of control cycles run."""
        return int(self.t_s.size)

    @property
    def rows(self) -> int:
        """Number of rows kept."""
        return int(len(self.q))

    @property
    def row_time_s(self) -> np.ndarray:
        """Each row's time (R,) [s]."""
        return self.t_s[self.cycle]

    @property
    def row_tick(self) -> np.ndarray:
        """Each row's tick (R,)."""
        return self.tick[self.cycle]

    def sums(self) -> RunStats:
        """The sums over every cycle.

        Raises:
            ControlError: A log made by hand, or by ``run(rows=False)`` (no sums).
        """
        if self.stats is None:
            raise ControlError("this RunLog has no sums over its cycles (a log made by hand, or by "
                               "run(rows=False), which keeps only the cycles' times and ticks)")
        return self.stats

    def error_sums(self) -> ColumnStats:
        """The joint tracking error's sums over every cycle.

        Raises:
            ControlError: No error summed (the loop sums it for a joint reference and a controller
                with a joint map).
        """
        error = self.sums().error
        if error is None:
            raise ControlError("the control loop summed no joint tracking error (a joint reference and a "
                               "controller with a joint map are needed)")
        return error


def log_stride(n_cycles: int, max_rows: int) -> int:
    """Cycles between kept rows so that every ``stride``-th cycle and the last fit ``max_rows``.

    Args:
        n_cycles: Cycles of the run.
        max_rows: Rows at most (>= 2).
    """
    if max_rows < 2:
        raise ControlError(f"max_rows must be >= 2 (the first and the last cycle); got {max_rows}")
    return max(1, -(-(n_cycles - 1) // (max_rows - 1)))


def log_rows(n_cycles: int, stride: int) -> int:
    """Rows a log of ``n_cycles`` keeps at ``stride``: cycles 0, stride, 2 stride, ... and the last."""
    return len(kept_cycles(n_cycles, stride)) if n_cycles > 0 else 0


def kept_cycles(n_cycles: int, stride: int) -> np.ndarray:
    """The cycles a log of ``n_cycles`` keeps at ``stride`` (0, stride, 2 stride, ... and the last)."""
    cycles = np.arange(0, n_cycles, stride)
    return np.append(cycles, n_cycles - 1) if n_cycles and (n_cycles - 1) % stride else cycles


def batch_rows(k0: int, b: int, stride: int) -> tuple[np.ndarray, np.ndarray]:
    """Where a batch of cycles ``k0 .. k0 + b - 1`` goes in a log kept at ``stride``.

    Cycle k goes to row ceil(k / stride): kept when k is a multiple of the stride, overwritten by the
    next cycle otherwise. The batch's last cycle is written too (the run's last cycle is always kept:
    a later batch overwrites it when it is not).

    Returns:
        The batch's entries to write (indices into the batch, increasing) and their rows (unique).
    """
    cycles = np.arange(k0, k0 + b)
    at = np.flatnonzero(cycles % stride == 0)
    if b and (not at.size or at[-1] != b - 1):
        at = np.append(at, b - 1)
    return at, -(-cycles[at] // stride)


class _Sums:
    """Per-column sums of q, v, command (and the joint error ``q_ref - q``) over blocks of cycles."""

    def __init__(self, nq: int, nv: int, m: int, idx_q: np.ndarray | None):
        self.cols = np.cumsum([0, nq, nv, m, 0 if idx_q is None else idx_q.size])
        self.idx_q = idx_q
        width = int(self.cols[-1])
        self.count = 0
        self.min = np.full(width, np.inf)
        self.max = np.full(width, -np.inf)
        self.sum = np.zeros(width)
        self.sum_sq = np.zeros(width)
        c = self.cols
        self.q_, self.v_, self.cmd_, self.err_ = (slice(int(c[i]), int(c[i + 1])) for i in range(4))

    def add(self, q: np.ndarray, v: np.ndarray, cmd: np.ndarray, ref_q: np.ndarray | None) -> None:
        """Add a block of cycles (rows): q, v, command and, with ``idx_q``, the reference's positions."""
        parts = [q, v, cmd]
        if self.idx_q is not None:
            parts.append(ref_q - q[:, self.idx_q])  # type: ignore[operator]
        b = np.hstack(parts)
        np.minimum(self.min, b.min(axis=0), out=self.min)
        np.maximum(self.max, b.max(axis=0), out=self.max)
        self.sum += b.sum(axis=0)
        self.sum_sq += np.einsum("ij,ij->j", b, b)
        self.count += len(b)

    def stats(self) -> RunStats:
        """The sums so far."""

        def part(s: slice) -> ColumnStats:
            return ColumnStats(self.count, self.min[s].copy(), self.max[s].copy(), self.sum[s].copy(),
                               self.sum_sq[s].copy())

        return RunStats(part(self.q_), part(self.v_), part(self.cmd_),
                        None if self.idx_q is None else part(self.err_))


class LogWriter:
    """Fills a :class:`RunLog` during a run of ``n_cycles``, :data:`LOG_BATCH` cycles at a time.

    Each cycle's values are copied into small staging arrays as the cycle ends (:meth:`keep`: a few
    row stores, while the state and command are still in the CPU's caches); every ``batch`` cycles
    the staged rows go into the kept rows and the sums (:meth:`write`) with one numpy call per
    field. Keeping the cycle's objects instead and reading them back a batch at a time read them
    cold, and released them all at once: about 1 ms a 256-cycle batch on a 29-joint humanoid.

    Args:
        n_cycles: Cycles the run may take (the arrays are allocated for them).
        nq: Width of q.
        nv: Width of v.
        k_ref: Width of the reference (0: none logged).
        idx_q: For a joint reference: q's entries the reference's positions track (the tracking
            error ``q_ref - q`` is summed), else None.
        max_rows: Rows of q, v, command and reference kept at most.
        batch: Cycles staged before they are written.
        rows: False: keep every cycle's time and tick only (:meth:`keep_times`; no rows, no sums).
    """

    def __init__(self, n_cycles: int, nq: int, nv: int, k_ref: int, idx_q: np.ndarray | None,
                 max_rows: int = MAX_LOG_ROWS, batch: int = LOG_BATCH, rows: bool = True):
        self.stride = log_stride(n_cycles, max_rows)
        self.batch = batch = max(1, min(batch, n_cycles))
        self.rows = rows
        n_rows = log_rows(n_cycles, self.stride) if rows else 0
        self.nq, self.nv, self.idx_q = nq, nv, idx_q
        self.t = np.empty(n_cycles)
        self.tick = np.empty(n_cycles, dtype=np.int64)
        self.cycle = np.empty(n_rows, dtype=np.int64)
        self.q = np.empty((n_rows, nq))
        self.v = np.empty((n_rows, nv))
        self.ref = np.empty((n_rows, k_ref))
        self.ref_v = np.empty((n_rows, k_ref))
        self.cmd = np.empty((n_rows, 0))  # sized by the first command (its width is the controller's)
        self.sums: _Sums | None = None
        self.n = 0  # cycles written
        self.staged = 0  # cycles staged since (kept, not yet written)
        self._q, self._v = np.empty((batch, nq)), np.empty((batch, nv))
        self._ref, self._ref_v = np.empty((batch, k_ref)), np.empty((batch, k_ref))
        self._cmd = np.empty((batch, 0))
        self._logs_ref = k_ref > 0

    def keep(self, state: RobotState, reference: object, command: Command) -> None:
        """Stage one cycle (its state, reference and command are copied); a full batch is written."""
        i = self.staged
        if i == 0 and self.sums is None:  # the first cycle: the command's width is the controller's
            m = command.values.size
            self.cmd = np.empty((len(self.cycle), m))
            self._cmd = np.empty((self.batch, m))
            self.sums = _Sums(self.nq, self.nv, m, self.idx_q)
        k = self.n + i
        self.t[k] = state.time_s
        self.tick[k] = state.tick
        self._q[i] = state.q
        self._v[i] = state.v
        self._cmd[i] = command.values
        if self._logs_ref:
            self._ref[i] = reference[0]  # type: ignore[index]
            self._ref_v[i] = reference[1]  # type: ignore[index]
        self.staged = i + 1
        if i + 1 == self.batch:
            self.write()

    def keep_times(self, state: RobotState, reference: object, command: Command) -> None:
        """:meth:`keep` for a log without rows: the cycle's time and tick."""
        k = self.n
        self.t[k] = state.time_s
        self.tick[k] = state.tick
        self.n = k + 1

    def write(self) -> None:
        """Write the cycles staged so far into the kept rows and the sums."""
        b = self.staged
        if not b:
            return
        k0 = self.n
        q, v, cmd = self._q[:b], self._v[:b], self._cmd[:b]
        ref = self._ref[:b] if self._logs_ref else None
        at, rows = batch_rows(k0, b, self.stride)
        self.cycle[rows] = k0 + at
        self.q[rows] = q[at]
        self.v[rows] = v[at]
        self.cmd[rows] = cmd[at]
        if ref is not None:
            self.ref[rows] = ref[at]
            self.ref_v[rows] = self._ref_v[at]
        self.sums.add(q, v, cmd, ref if self.idx_q is not None else None)  # type: ignore[union-attr]
        self.n = k0 + b
        self.staged = 0

    def log(self, wall_s: float) -> RunLog:
        """The log of the cycles written (call :meth:`write` first)."""
        n, kept = self.n, log_rows(self.n, self.stride) if self.rows else 0
        return RunLog(self.t[:n], self.q[:kept], self.v[:kept], self.cmd[:kept], self.ref[:kept],
                      self.ref_v[:kept], wall_s, self.tick[:n], self.cycle[:kept], self.stride,
                      self.sums.stats() if self.sums is not None else None)
