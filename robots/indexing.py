"""Index sets as slices where they can be: the one helper every index array goes through.

A contiguous increasing run of indices indexes numpy arrays as a slice: a view (no copy) on read,
an in-place write on assignment, and no fancy-indexing cost (~1 us per call on small vectors).
Index arrays that are not contiguous stay arrays. Derive them once (at construction), never per
cycle.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt


def as_slice(indices: npt.ArrayLike) -> slice | np.ndarray:
    """``indices`` as a slice when they are a contiguous increasing run, else an int array.

    An empty set is the empty slice ``slice(0, 0)`` (indexing with it selects nothing).

    Args:
        indices: Integer indices (n,).

    Returns:
        ``slice(i0, i0 + n)`` for ``i0, i0 + 1, ..., i0 + n - 1``; otherwise the indices as a
        read-only int array.
    """
    idx = np.asarray(indices, dtype=int).reshape(-1)
    if idx.size == 0:
        return slice(0, 0)
    start = int(idx[0])
    if np.array_equal(idx, np.arange(start, start + idx.size)):
        return slice(start, start + idx.size)
    idx = idx.copy()
    idx.setflags(write=False)
    return idx
