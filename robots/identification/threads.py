"""One BLAS thread for identification's small dense algebra.

The matrices here have at most a few hundred columns (QR and SVD of the stacked equations, the
barrier's Newton steps, the excitation design's regressor), where a threaded BLAS spends more on
spinning its threads than it gains, and on a busy machine (other processes on the cores) loses
10x: a 30 s G1 log took 50 s to identify with OpenBLAS's default threads against 4.6 s with one
(the same load, the same run). ``single_threaded_blas`` limits the BLAS pool for a block.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

from threadpoolctl import threadpool_limits


@contextlib.contextmanager
def single_threaded_blas() -> Iterator[None]:
    """Run the block with one BLAS thread (restored afterwards)."""
    with threadpool_limits(limits=1, user_api="blas"):
        yield
