"""Tiny benchmark harness: medians of repeated timings, ratios measured in the same run."""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable


def interleaved(fns: dict[str, Callable[[], object]], repeats: int = 9,
                timer: Callable[[], float] = time.perf_counter) -> dict[str, float]:
    """Median time [s] of each function, runs interleaved so machine noise hits all alike.

    ``timer=time.thread_time`` counts this thread's CPU time only: on a machine others share,
    the time the thread waits for a core is left out (cache and clock effects are not).
    """
    for fn in fns.values():
        fn()
    samples: dict[str, list[float]] = {k: [] for k in fns}
    for _ in range(repeats):
        for name, fn in fns.items():
            t0 = timer()
            fn()
            samples[name].append(timer() - t0)
    return {k: statistics.median(v) for k, v in samples.items()}
