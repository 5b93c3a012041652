"""The sweep's figure: a metric over one option (mean and std over the rest) or a heat map over two.

The options plotted are those with more than one value, the seed excepted: the seeds (and any
third option) are averaged over. Text values (controller names) are placed in their grid order.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from mbctl.sim.atomic import write_bytes_atomic


def _number(text: Any) -> float:
    """A CSV cell as a float (true/false as 1/0); NaN when it is not a number."""
    if isinstance(text, str) and text.lower() in ("true", "false"):
        return 1.0 if text.lower() == "true" else 0.0
    try:
        return float(text)
    except (TypeError, ValueError):
        return math.nan


def _levels(rows: list[dict[str, Any]], name: str) -> list[str]:
    """The option's distinct values in first-seen order."""
    return list(dict.fromkeys(str(r[name]) for r in rows))


def _axis(levels: list[str]) -> tuple[np.ndarray, bool]:
    """Positions of ``levels``: their values if all are numbers, else 0, 1, 2 … (categorical)."""
    x = np.array([_number(v) for v in levels])
    return (x, True) if np.all(np.isfinite(x)) else (np.arange(len(levels), dtype=float), False)


def plot_sweep(rows: list[dict[str, Any]], names: list[str], metric: str, title: str,
               path: Path) -> Path | None:
    """Draw ``metric`` over the swept options into ``path`` (PNG).

    Args:
        rows: The sweep's rows (CSV cells).
        names: The swept options, in column order.
        metric: The report value to draw.
        title: The figure title.
        path: The PNG to write.

    Returns:
        The path, or None when no row has the metric or nothing varies.
    """
    if not rows or not any(metric in r and np.isfinite(_number(r[metric])) for r in rows):
        return None
    varied = [n for n in names if n != "seed" and len(_levels(rows, n)) > 1]
    if not varied:
        return None
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.4, 4.4), layout="constrained")
    ax = fig.add_subplot()
    if len(varied) == 1:
        _line(ax, rows, varied[0], metric)
    else:
        _heat(fig, ax, rows, varied[0], varied[1], metric)
    rest = [n for n in names if n not in varied[:2] and len(_levels(rows, n)) > 1]
    fig.suptitle(title + (f" (mean over {', '.join(rest)})" if rest else ""), fontsize=10)
    return write_bytes_atomic(path, lambda f: fig.savefig(f, format="png", dpi=110))


def _line(ax: Any, rows: list[dict[str, Any]], name: str, metric: str) -> None:
    levels = _levels(rows, name)
    x, numeric = _axis(levels)
    groups = [[_number(r.get(metric)) for r in rows if str(r[name]) == lv] for lv in levels]
    mean = np.array([np.nanmean(g) if np.isfinite(g).any() else np.nan for g in groups])
    std = np.array([np.nanstd(g) if np.isfinite(g).any() else np.nan for g in groups])
    ax.plot(x, mean, "o-", label="mean")
    if any(len(g) > 1 for g in groups):
        ax.fill_between(x, mean - std, mean + std, alpha=0.25, label="± std")
        ax.legend(fontsize=8)
    if not numeric:
        ax.set_xticks(x, levels)
    ax.set_xlabel(name)
    ax.set_ylabel(metric)
    ax.grid(alpha=0.3)


def _heat(fig: Any, ax: Any, rows: list[dict[str, Any]], x_name: str, y_name: str, metric: str) -> None:
    xs, ys = _levels(rows, x_name), _levels(rows, y_name)
    grid = np.full((len(ys), len(xs)), np.nan)
    for j, yv in enumerate(ys):
        for i, xv in enumerate(xs):
            vals = [_number(r.get(metric)) for r in rows if str(r[x_name]) == xv and str(r[y_name]) == yv]
            if np.isfinite(vals).any():
                grid[j, i] = np.nanmean(vals)
    image = ax.imshow(grid, origin="lower", aspect="auto", cmap="viridis")
    ax.set_xticks(range(len(xs)), xs)
    ax.set_yticks(range(len(ys)), ys)
    ax.set_xlabel(x_name)
    ax.set_ylabel(y_name)
    middle = np.nanmean([np.nanmin(grid), np.nanmax(grid)])
    for j in range(len(ys)):
        for i in range(len(xs)):
            if np.isfinite(grid[j, i]):  # dark text on the bright half of viridis
                ax.text(i, j, f"{grid[j, i]:.3g}", ha="center", va="center", fontsize=7,
                        color="k" if grid[j, i] > middle else "w")
    fig.colorbar(image, ax=ax, label=metric)
