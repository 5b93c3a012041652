"""Per-step CSV recording with named columns, streamed row by row.

Columns are named with units where they are ambiguous (``time_s``, ``base_z_m``,
``q_<joint>_rad``, ``target_<actuator>``, ``<sensor>[i]``). Every row is written whole and
flushed as it is produced, so an error, a divergence or Ctrl-C leaves every completed row on
disk, never a torn one (the job's report says whether the run completed).
"""

from __future__ import annotations

import csv
import os
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import numpy as np

from mbctl.sim.atomic import FILE_MODE
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


class CsvStream:
    """A CSV file written one whole row at a time, each row flushed to the OS as it is written.

    The header is written on open. A row is one ``write`` of a complete line followed by a flush:
    an interruption (an exception, Ctrl-C, SIGTERM handled as an exception) between rows leaves
    only complete rows. Use as a context manager or call ``close()``.

    Args:
        path: CSV file to create (replaces an existing file).
        header: Column names (with units, e.g. ``time_s``).
    """

    def __init__(self, path: str | os.PathLike, header: Sequence[str]):
        self.path = Path(path)
        self.header = tuple(header)
        if len(set(self.header)) != len(self.header):
            dup = sorted({h for h in self.header if self.header.count(h) > 1})
            raise ValueError(f"CSV columns must be unique; repeated: {dup}")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = open(self.path, "w", newline="", encoding="utf-8")  # noqa: SIM115 - close()
        os.chmod(self.path, FILE_MODE)
        head = ",".join(self.header) + "\n"
        self._file.write(head)
        self._file.flush()
        # (rows, bytes on disk, last row), replaced in one assignment after each row is on disk,
        # so an interruption anywhere leaves it either before or after that row (see close()).
        self._state: tuple[int, int, Sequence[float]] = (0, len(head.encode()), ())
        self._pending: Sequence[float] = ()

    @property
    def rows(self) -> int:
        """Complete rows on disk."""
        return self._state[0]

    @property
    def last(self) -> Sequence[float]:
        """The last row written (empty before the first)."""
        return self._state[2]

    @property
    def closed(self) -> bool:
        """True once ``close()`` ran."""
        return self._file.closed

    def write(self, values: Sequence[float]) -> None:
        """Append one row (as many values as columns; floats written exactly with ``repr``).

        Raises:
            ValueError: The row has another length than the header.
        """
        if len(values) != len(self.header):
            raise ValueError(f"a row of {self.path.name} has {len(self.header)} values; got {len(values)}")
        line = ",".join([repr(float(x)) for x in values]) + "\n"  # ASCII: len is the byte count
        rows, size, _ = self._state
        self._pending = values
        self._file.write(line)
        self._file.flush()
        self._state = (rows + 1, size + len(line), values)

    def close(self) -> Path:
        """Flush and close (idempotent); returns the path."""
        if not self._file.closed:
            self._file.flush()
            os.fsync(self._file.fileno())
            rows, size, _ = self._state
            if os.fstat(self._file.fileno()).st_size > size:  # interrupted after the row's write
                self._state = (rows + 1, os.fstat(self._file.fileno()).st_size, self._pending)
            self._file.close()
        return self.path

    def __enter__(self) -> CsvStream:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class Recorder:
    """Streams one CSV row per ``record()`` call, read from the simulator by ``columns``.

    Args:
        path: CSV file to create, or an open CsvStream whose header is the columns' names.
        columns: The columns, in order.

    Raises:
        ValueError: An open stream's header does not match the columns.
    """

    def __init__(self, path: str | os.PathLike | CsvStream, columns: Sequence[Column]):
        self.columns = list(columns)
        self._reads = [c.read for c in self.columns]
        names = tuple(c.name for c in self.columns)
        self.stream = path if isinstance(path, CsvStream) else CsvStream(path, names)
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
