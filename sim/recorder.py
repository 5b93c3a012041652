"""Per-step CSV recording with named columns, streamed through a :class:`CsvStream`.

Columns are named with units where they are ambiguous (``time_s``, ``base_z_m``,
``q_<joint>_rad``, ``target_<actuator>``, ``<sensor>[i]``). Every row is written whole; an
error, a divergence or Ctrl-C leaves every completed row on disk, never a torn one (the job's
report says whether the run completed). See :mod:`mbctl.sim.csv_stream` for the flushing.
"""

from __future__ import annotations

import csv
import os
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import numpy as np

from mbctl.sim.csv_stream import CsvStream
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
        cols.append(Column(f"q_{name}_{unit}", partial(_qpos, j.qposadr)))
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
    """Streams one CSV row per ``record()`` call, read from the simulator by ``columns``.

    Args:
        path: CSV file to create, or an open CsvStream whose header is the columns' names.
        columns: The columns, in order.
        flush_interval_s: For a file created here: how long [s] a row may wait in memory. The
            default 0 writes each row through at once (a script reading the file while it runs
            sees every row); the job runner's streams wait up to 50 ms and format in bulk.

    Raises:
        ValueError: An open stream's header does not match the columns.
        OutputPathError: A symlink or a non-regular file at ``path``.
    """

    def __init__(self, path: str | os.PathLike | CsvStream, columns: Sequence[Column], *,
                 flush_interval_s: float = 0.0):
        self.columns = list(columns)
        self._reads = [c.read for c in self.columns]
        names = tuple(c.name for c in self.columns)
        self.stream = (path if isinstance(path, CsvStream)
                       else CsvStream(path, names, flush_interval_s=flush_interval_s))
        if self.stream.header != names:
            raise ValueError(f"the stream's header {self.stream.header} is not the columns' {names}")

    @property
    def path(self) -> Path:
        """Path of the CSV."""
        return self.stream.path

    @property
    def rows(self) -> int:
        """Rows written so far."""
        return self.stream.rows

    def record(self, sim: Simulator) -> None:
        """Append one row read from ``sim``."""
        self.stream.write([read(sim) for read in self._reads])

    def close(self) -> Path:
        """Flush and close the file (idempotent)."""
        return self.stream.close()

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
