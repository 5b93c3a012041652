"""Wall-clock pacing for the real-time plants (DDS interface, bridge): deadlines, GIL-free sleep, statistics.

A free-running loop (the bridge) calls ``wait()``; a loop paced by the robot's state stream (the
DDS interface) calls ``mark()`` when its state arrives.

Cycle k should start at t_k = t_0 + k T. ``wait()`` ends cycle k: if the cycle's compute and IO
ran past t_{k+1} it counts a deadline miss and starts the next cycle at once, re-anchoring the
grid there (no burst of catch-up cycles); otherwise it sleeps until t_{k+1} (``time.sleep`` is a
``clock_nanosleep``, which releases the GIL; Linux wakes within ~0.1 ms).

Each cycle's work (its compute and IO, from its start to ``wait()`` or ``work_done()``) is timed
twice: in wall-clock time and in the loop thread's CPU time. A cycle whose work took longer than
the period in wall time but not in CPU time was waiting for a core (the machine's other work), not
computing: ``cpu_overruns`` counts the cycles whose CPU time alone overran.

A loop's process can run at real-time priority (:class:`RealtimePriority`: ``SCHED_FIFO`` at
``REALTIME_PRIORITY``, where the OS permits it), so the machine's other work does not keep it
from a core when its state arrives; it still sleeps between cycles, so it does not starve them.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PeriodStats:
    """What the clock measured over a run.

    Attributes:
        cycles: Completed cycles.
        period_p50_ms: Median time between cycle starts [ms].
        period_p99_ms: 99th percentile of it [ms].
        period_max_ms: Longest [ms].
        deadline_misses: Cycles whose compute and IO overran the period.
        work_p99_ms: 99th percentile of a cycle's compute and IO, wall-clock time [ms].
        work_cpu_p99_ms: The same in the loop thread's CPU time [ms].
        cpu_overruns: Cycles whose CPU time alone exceeded the period.
    """

    cycles: int
    period_p50_ms: float
    period_p99_ms: float
    period_max_ms: float
    deadline_misses: int
    work_p99_ms: float = float("nan")
    work_cpu_p99_ms: float = float("nan")
    cpu_overruns: int = 0


class CycleClock:
    """Paces a loop to ``period_s`` of wall-clock time and measures it.

    Args:
        period_s: The control period [s].
        capacity: Cycles whose start times are kept for the statistics (a ring after that).
    """

    def __init__(self, period_s: float, capacity: int = 1 << 18):
        self.period_s = float(period_s)
        self._starts = np.empty(capacity)
        self._work = np.full((capacity, 2), np.nan)  # per cycle: work wall, CPU time [s]
        self._n = 0
        self.deadline_misses = 0
        self._next = 0.0
        self._cpu_start = 0.0

    def start(self) -> float:
        """Start cycle 0 now; its time (``time.perf_counter``) [s]."""
        now = time.perf_counter()
        self._n = 0
        self.deadline_misses = 0
        self._work[:] = np.nan
        self._record(now)
        self._next = now + self.period_s
        return now

    def _record(self, t: float) -> None:
        k = self._n % len(self._starts)
        self._starts[k] = t
        self._work[k] = np.nan
        self._n += 1
        self._cpu_start = time.thread_time()

    def work_done(self) -> float:
        """The current cycle's compute and IO end now (its wait begins); the time [s]."""
        now = time.perf_counter()
        k = (self._n - 1) % len(self._starts)
        self._work[k] = (now - self._starts[k], time.thread_time() - self._cpu_start)
        return now

    def wait(self) -> float:
        """End the cycle: sleep to the next deadline, or count a miss; the next cycle's start [s]."""
        now = self.work_done()
        if now > self._next:
            self.deadline_misses += 1
            self._next = now
        else:
            time.sleep(self._next - now)
            now = time.perf_counter()
        self._record(now)
        self._next += self.period_s
        return now

    def mark(self, overran: bool) -> float:
        """Start the next cycle now, for a loop paced by something else (the robot's state stream).

        Args:
            overran: The cycle that ends overran its period (counted as a deadline miss).

        Returns:
            The next cycle's start [s].
        """
        now = time.perf_counter()
        self.deadline_misses += bool(overran)
        self._record(now)
        self._next = now + self.period_s
        return now

    @property
    def deadline(self) -> float:
        """When the current cycle should end (``time.perf_counter``) [s]."""
        return self._next

    @property
    def cycles(self) -> int:
        """Cycles started."""
        return self._n

    def stats(self) -> PeriodStats:
        """The statistics so far (NaN periods before two cycles)."""
        n = min(self._n, len(self._starts))
        if self._n > len(self._starts):  # the ring wrapped: unroll it in time order
            k = self._n % len(self._starts)
            starts = np.concatenate([self._starts[k:], self._starts[:k]])
        else:
            starts = self._starts[:n]
        work = self._work[:n][~np.isnan(self._work[:n, 0])] * 1e3
        if work.size:
            work_stats = (float(np.percentile(work[:, 0], 99)), float(np.percentile(work[:, 1], 99)),
                          int(np.count_nonzero(work[:, 1] > self.period_s * 1e3)))
        else:
            work_stats = (float("nan"), float("nan"), 0)
        periods_ms = np.diff(starts) * 1e3
        if periods_ms.size == 0:
            return PeriodStats(self._n, float("nan"), float("nan"), float("nan"), self.deadline_misses,
                               *work_stats)
        return PeriodStats(self._n, float(np.median(periods_ms)), float(np.percentile(periods_ms, 99)),
                           float(periods_ms.max()), self.deadline_misses, *work_stats)


#: The ``SCHED_FIFO`` priority of the real-time loops (1..99: above every normal thread, below the
#: kernel's own threads, which run at 50 and up).
REALTIME_PRIORITY = 20


class RealtimePriority:
    """Every thread of the process at ``SCHED_FIFO`` ``REALTIME_PRIORITY`` (20) until :meth:`release`.

    Every thread of the process, not only the loop's: the loop waits on the others (DDS's receive
    threads deliver its states; a thread of the job's, a CSV flusher, may hold the GIL or a lock
    the loop needs), and a normal-priority holder preempted by the machine's other work would hold
    a real-time loop up for as long (priority inversion: measured 50-130 ms stalls with the loop's
    thread alone raised). Threads started later keep their own priority. Linux only, and only with
    the permission (root, ``CAP_SYS_NICE`` or an ``rtprio`` limit); elsewhere :meth:`acquire` leaves
    the threads as they were and says so.
    """

    def __init__(self) -> None:
        self._saved: list[tuple[int, int, os.sched_param]] = []  # thread id, policy, parameters

    @property
    def active(self) -> bool:
        """Whether the threads run at real-time priority now."""
        return bool(self._saved)

    def acquire(self) -> bool:
        """Raise the process's threads to real-time priority; whether it was permitted (idempotent)."""
        if self._saved:
            return True
        try:
            tids = [int(t) for t in os.listdir("/proc/self/task")]
            param = os.sched_param(REALTIME_PRIORITY)
            for tid in tids:
                try:
                    saved = (tid, os.sched_getscheduler(tid), os.sched_getparam(tid))
                    os.sched_setscheduler(tid, os.SCHED_FIFO, param)
                except ProcessLookupError:  # the thread ended meanwhile
                    continue
                self._saved.append(saved)
        except (AttributeError, OSError):  # not Linux, or not permitted
            self.release()
            return False
        return True

    def release(self) -> None:
        """Back to each thread's own scheduling (from any thread; idempotent)."""
        saved, self._saved = self._saved, []
        for tid, policy, param in saved:
            try:
                os.sched_setscheduler(tid, policy, param)
            except OSError:  # the thread has ended
                pass
