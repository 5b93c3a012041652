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

#: The unit each numeric option is given in on the command line (``jobs/options.py``), for the
#: axis labels: a sweep's option axis reads in the user's units.
OPTION_UNITS = {"model_error": "%", "duration": "s", "omega": "rad/s", "zeta": "-", "side": "m",
                "speed": "m/s", "impulse": "N s", "direction": "deg", "delta": "rad", "tol": "m",
                "max_rms_mm": "mm", "max_rms_rad": "rad"}
#: How a report value is shown, by the unit suffix of its key: (suffix, unit shown, scale).
#: Lengths in mm (the errors are mm-sized), fractions ("rel_error": of m g) and booleans in %.
VALUE_UNITS = (("_m", "mm", 1e3), ("_rad", "rad", 1.0), ("_us", "us", 1.0), ("_s", "s", 1.0),
               ("_N", "N", 1.0), ("_pct", "%", 1.0))


def value_label(metric: str, rows: list[dict[str, Any]]) -> tuple[str, float]:
    """(axis label with unit, scale from the stored value) of report value ``metric``."""
    cells = [str(r.get(metric, "")).lower() for r in rows]
    if all(c in ("true", "false", "") for c in cells):
        return f"{metric.replace('_', ' ')} (% of runs)", 100.0
    for suffix, unit, scale in VALUE_UNITS:
        if metric.endswith(suffix):
            return f"{metric[: -len(suffix)].replace('_', ' ')} ({unit})", scale
    if "rel_error" in metric:
        return f"{metric.replace('_', ' ')} (% of m g)", 100.0
    return metric.replace("_", " "), 1.0


def option_label(name: str) -> str:
    """An option's axis label with the unit it is given in (``model_error (%)``)."""
    unit = OPTION_UNITS.get(name)
    return f"{name.replace('_', ' ')} ({unit})" if unit else name.replace("_", " ")


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


def _tick(text: str) -> str:
    """A level as a tick label: numbers shortest (``10.0`` -> ``10``), text as it is."""
    value = _number(text)
    return f"{value:g}" if np.isfinite(value) and text.lower() not in ("true", "false") else text


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
    fig = sweep_figure(rows, names, varied, metric, title)
    return write_bytes_atomic(path, lambda f: fig.savefig(f, format="png", dpi=110))


def sweep_figure(rows: list[dict[str, Any]], names: list[str], varied: list[str], metric: str,
                 title: str) -> Any:
    """The figure of :func:`plot_sweep`: ``metric`` over the first one or two ``varied`` options."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.4, 4.4), layout="constrained")
    ax = fig.add_subplot()
    if len(varied) == 1:
        _line(ax, rows, varied[0], metric)
    else:
        _heat(fig, ax, rows, varied[0], varied[1], metric)
    rest = [n for n in names if n not in varied[:2] and len(_levels(rows, n)) > 1]
    fig.suptitle(title + (f" (mean over {', '.join(rest)})" if rest else ""), fontsize=10)
    return fig


def _line(ax: Any, rows: list[dict[str, Any]], name: str, metric: str) -> None:
    levels = _levels(rows, name)
    x, numeric = _axis(levels)
    label, scale = value_label(metric, rows)
    groups = [[scale * _number(r.get(metric)) for r in rows if str(r[name]) == lv] for lv in levels]
    mean = np.array([np.nanmean(g) if np.isfinite(g).any() else np.nan for g in groups])
    std = np.array([np.nanstd(g) if np.isfinite(g).any() else np.nan for g in groups])
    ax.plot(x, mean, "o-", label="mean")
    if any(len(g) > 1 for g in groups):
        ax.fill_between(x, mean - std, mean + std, alpha=0.25, label="± std")
        ax.legend(fontsize=8)
    if not numeric:
        ax.set_xticks(x, levels)
    ax.set_xlabel(option_label(name))
    ax.set_ylabel(label)
    ax.grid(alpha=0.3)


def _heat(fig: Any, ax: Any, rows: list[dict[str, Any]], x_name: str, y_name: str, metric: str) -> None:
    xs, ys = _levels(rows, x_name), _levels(rows, y_name)
    label, scale = value_label(metric, rows)
    grid = np.full((len(ys), len(xs)), np.nan)
    for j, yv in enumerate(ys):
        for i, xv in enumerate(xs):
            vals = [scale * _number(r.get(metric)) for r in rows
                    if str(r[x_name]) == xv and str(r[y_name]) == yv]
            if np.isfinite(vals).any():
                grid[j, i] = np.nanmean(vals)
    image = ax.imshow(grid, origin="lower", aspect="auto", cmap="viridis")
    ax.set_xticks(range(len(xs)), [_tick(v) for v in xs])
    ax.set_yticks(range(len(ys)), [_tick(v) for v in ys])
    ax.set_xlabel(option_label(x_name))
    ax.set_ylabel(option_label(y_name))
    middle = np.nanmean([np.nanmin(grid), np.nanmax(grid)])
    for j in range(len(ys)):
        for i in range(len(xs)):
            if np.isfinite(grid[j, i]):  # dark text on the bright half of viridis
                ax.text(i, j, f"{grid[j, i]:.3g}", ha="center", va="center", fontsize=7,
                        color="k" if grid[j, i] > middle else "w")
    fig.colorbar(image, ax=ax, label=label)
