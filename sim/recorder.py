"""Per-step CSV recording with named columns, written atomically.

Columns are named with units where they are ambiguous (``time_s``, ``base_z_m``,
``q_<joint>_rad``, ``target_<actuator>``, ``<sensor>[i]``). The file appears only when the
recorder closes — also after an error, with every complete row taken so far — never torn.
"""

from __future__ import annotations

import csv
import os
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import numpy as np

from mbctl.sim.atomic import AtomicFile
from mbctl.sim.simulator import Simulator


@dataclass(frozen=True)
class Column:
    """One CSV column: its header and how to read its value from the simulator."""

    name: str
    read: Callable[[Simulator], float]


def _qpos(i: int, sim: Simulator) -> float:
    return float(sim.data.qpos[i])


def _ctrl(i: int, sim: Simulator) -> float:
    return float(sim.data.ctrl[i])


def _sensor_channel(adr: int, sim: Simulator) -> float:
    sim.forward()  # sensors are derived quantities: bring them up to the current state
    return float(sim.data.sensordata[adr])


def time_column() -> Column:
    """Simulated time [s]."""
    return Column("time_s", lambda sim: sim.time_s)


def joint_columns(sim: Simulator, joints: Iterable[str]) -> list[Column]:
    """Angles [rad] (or positions [m]) of 1-dof joints, one column each."""
    cols = []
    for name in joints:
        j = sim.robot.joint(name)
        unit = "m" if j.kind == "slide" else "rad"
        cols.append(Column(f"q_{name}_{unit}", partial(_qpos, j.idx_q)))
    return cols


def target_columns(sim: Simulator, actuators: Iterable[str]) -> list[Column]:
    """Current ctrl (target or torque) of actuators, one column each."""
    cols = []
    for name in actuators:
        a = sim.robot.actuator(name)
        cols.append(Column(f"ctrl_{name}_{a.kind}", partial(_ctrl, a.index)))
    return cols


def base_z_column() -> Column:
    """Floating-base height [m]."""
    return Column("base_z_m", lambda sim: sim.base_z_m)


def sensor_columns(sim: Simulator, sensors: Iterable[str]) -> list[Column]:
    """Every channel of the named sensors (``name[i]`` for multi-dimensional ones)."""
    cols = []
    for name in sensors:
        info = sim.robot.sensor(name)
        for k in range(info.dim):
            label = name if info.dim == 1 else f"{name}[{k}]"
            cols.append(Column(label, partial(_sensor_channel, info.data_slice.start + k)))
    return cols


class Recorder:
    """Writes one CSV row per ``record()`` call; use as a context manager.

    Args:
        path: CSV file to create (replaced atomically on close).
        columns: The columns, in order.
    """

    def __init__(self, path: str | os.PathLike, columns: Sequence[Column]):
        self.columns = list(columns)
        self._file = AtomicFile(path)
        self._writer = csv.writer(self._file.file)
        self._writer.writerow([c.name for c in self.columns])
        self.rows = 0

    @property
    def path(self) -> Path:
        """Final path of the CSV."""
        return self._file.path

    def record(self, sim: Simulator) -> None:
        """Append one row read from ``sim``."""
        self._writer.writerow([repr(float(c.read(sim))) for c in self.columns])
        self.rows += 1

    def close(self) -> Path:
        """Publish the file (idempotent)."""
        return self._file.close()

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def read_csv(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Read a recording back as ``{column: values}``."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    header, body = rows[0], np.array(rows[1:], dtype=float).reshape(-1, len(rows[0]))
    return {name: body[:, i] for i, name in enumerate(header)}
