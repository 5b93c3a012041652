"""Outputs of the control jobs: CSV from logged arrays, plant-side site positions, PNG figures.

Files are written atomically (temporary file, then rename); figures use the headless Agg backend.
"""

from __future__ import annotations

import csv
import os
from collections.abc import Mapping
from pathlib import Path

import mujoco
import numpy as np

from mbctl.robots.model_pair import Robot
from mbctl.sim.atomic import AtomicFile


def write_columns_csv(path: str | os.PathLike, columns: Mapping[str, np.ndarray]) -> Path:
    """Write equally long 1-D arrays as CSV columns (header = keys), atomically.

    Args:
        path: CSV file to create.
        columns: Column name (with its unit, e.g. ``time_s``) -> values (N,).

    Returns:
        The final path.
    """
    names = list(columns)
    table = np.column_stack([np.asarray(columns[n], dtype=float) for n in names])
    with AtomicFile(path) as f:
        writer = csv.writer(f.file)
        writer.writerow(names)
        writer.writerows(table.tolist())
    return Path(path)


def site_positions(robot: Robot, q_log: np.ndarray, site: str) -> np.ndarray:
    """World positions p_WS (N, 3) [m] of a site at logged configurations, from the *plant*.

    Uses MuJoCo's kinematics (``mj_kinematics``) on a scratch ``MjData``, so the measurement
    does not depend on the Pinocchio model the controller used.

    Args:
        robot: The model pair (its MuJoCo model is the plant).
        q_log: Configurations (N, nq), Pinocchio convention.
        site: Site name.
    """
    m = robot.mj_model
    d = mujoco.MjData(m)
    sid = robot.site_id(site)
    out = np.empty((len(q_log), 3))
    conv = robot.converter
    for k, q in enumerate(q_log):
        d.qpos[:] = conv.q_pin_to_mj(q)
        mujoco.mj_kinematics(m, d)
        out[k] = d.site_xpos[sid]
    return out


def save_figure(fig, path: str | os.PathLike) -> Path:  # noqa: ANN001 - matplotlib Figure
    """Save a matplotlib figure as PNG atomically and close it."""
    import matplotlib.pyplot as plt

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp.png")
    fig.savefig(tmp, dpi=110)
    plt.close(fig)
    os.replace(tmp, path)
    return path


def new_figure(rows: int = 1, cols: int = 1, size: tuple[float, float] = (10.0, 4.5)):  # noqa: ANN201
    """A headless (Agg) matplotlib figure and its axes."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt.subplots(rows, cols, figsize=size, squeeze=False)
