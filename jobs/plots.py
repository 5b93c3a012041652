"""Headless matplotlib figures for the jobs (Agg, no pyplot state shared with a user's session)."""

from __future__ import annotations

from typing import Any

import numpy as np


def new_figure(rows: int = 1, cols: int = 1, size: tuple[float, float] = (10.0, 4.5)) -> tuple[Any, Any]:
    """A headless (Agg) figure and its axes array (rows, cols)."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import pyplot as plt

    return plt.subplots(rows, cols, figsize=size, squeeze=False)


def joint_colors(names: tuple[str, ...] | list[str]) -> dict[str, Any]:
    """One colour per joint name, the same in every panel of a figure (tab10, then tab20b)."""
    from matplotlib import colormaps

    # tab10's ten distinct hues first (tab20 pairs near-identical shades), then tab20b's twenty
    cmap = [colormaps["tab10"](i) for i in range(10)] + [colormaps["tab20b"](i) for i in range(20)]
    return {n: cmap[i % len(cmap)] for i, n in enumerate(names)}


def most_moved(values: np.ndarray, k: int = 8) -> np.ndarray:
    """Indices of the ``k`` columns of ``values`` (N, n) with the largest range, largest first."""
    spread = np.ptp(values, axis=0) if values.size else np.zeros(values.shape[1])
    return np.argsort(spread)[::-1][: min(k, values.shape[1])]
