"""Headless matplotlib figures for the jobs (Agg, no pyplot state shared with a user's session)."""

from __future__ import annotations

from typing import Any

import numpy as np


def new_figure(rows: int = 1, cols: int = 1, size: tuple[float, float] = (10.0, 4.5),
               layout: str | None = None) -> tuple[Any, Any]:
    """A headless (Agg) figure and its axes array (rows, cols).

    Args:
        rows: Panel rows.
        cols: Panel columns.
        size: Figure size (width, height) [inch].
        layout: matplotlib layout engine; "constrained" keeps legends placed outside the axes in
            the figure. None: the caller lays out (``tight_layout``).
    """
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import pyplot as plt

    return plt.subplots(rows, cols, figsize=size, squeeze=False, layout=layout)


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


def coincident_groups(signals: list[np.ndarray] | tuple[np.ndarray, ...], columns: list[int] | np.ndarray,
                      rel_tol: float = 0.01) -> list[list[int]]:
    """Group ``columns`` whose traces lie on top of each other in every signal.

    Mirror-image joints often move identically; drawn separately, one trace hides the other and
    the legend names a line the reader cannot find. Two columns coincide when, in each signal
    (N, n), they never differ by more than ``rel_tol`` of that signal's range over ``columns``.

    Args:
        signals: Arrays (N, n) sharing their columns (e.g. joint deviation and joint torque).
        columns: Candidate column indices, in the order to keep.
        rel_tol: Tolerance as a fraction of each signal's range [-].

    Returns:
        Groups of column indices, in the order of their first member.
    """
    cols = [int(c) for c in columns]
    scales = [max(float(np.ptp(s[:, cols])) if s.size and cols else 0.0, 1e-300) for s in signals]
    groups: list[list[int]] = []
    for c in cols:
        for group in groups:
            head = group[0]
            if all(np.max(np.abs(s[:, c] - s[:, head])) <= rel_tol * scale
                   for s, scale in zip(signals, scales, strict=True)):
                group.append(c)
                break
        else:
            groups.append([c])
    return groups


def tracking_panels(ax_q: Any, ax_err: Any, t_s: np.ndarray, q_ref: np.ndarray, q: np.ndarray,
                    labels: list[str], colors: list[Any], title: str) -> None:
    """Joint angles (plant solid in the joint's colour, reference dashed black on top) and errors.

    Args:
        ax_q: Axes of the angles [rad].
        ax_err: Axes of the errors q_ref - q [mrad], same colours; carries the legend, outside on
            the right.
        t_s: Times (N,) [s].
        q_ref: Reference angles (N, k) [rad].
        q: Plant angles (N, k) [rad].
        labels: Legend label per column (k).
        colors: Colour per column (k).
        title: What the row shows (e.g. "left leg").
    """
    for i, (label, color) in enumerate(zip(labels, colors, strict=True)):
        ax_q.plot(t_s, q[:, i], lw=2.0, color=color, label=label)
        ax_err.plot(t_s, (q_ref[:, i] - q[:, i]) * 1e3, lw=1.0, color=color, label=label)
    for i in range(len(labels)):
        ax_q.plot(t_s, q_ref[:, i], ls="--", lw=0.8, color="k", label="reference" if i == 0 else None)
    ax_q.set_ylabel("joint angle (rad)")
    ax_q.set_title(f"{title}: plant (solid), reference (dashed)", fontsize=9)
    ax_err.set_ylabel("q_ref - q (mrad)")
    ax_err.set_title(f"{title}: tracking error", fontsize=9)
    for ax in (ax_q, ax_err):
        ax.grid(True, alpha=0.3)
        ax.set_xlabel("time (s)")
    handles, names = ax_q.get_legend_handles_labels()
    ax_err.legend(handles, names, fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
