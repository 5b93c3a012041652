"""Per-step CSV recording with named columns, streamed through a :class:`CsvStream`.

Columns are named with units where they are ambiguous (``time_s``, ``base_z_m``,
``q_<joint>_rad``, ``target_<actuator>``, ``<sensor>[i]``). Every row is written whole; an
error, a divergence or Ctrl-C leaves every completed row on disk, never a torn one (the job's
report says whether the run completed). See :mod:`mbctl.sim.csv_stream` for the flushing.

The CSV keeps every row on disk; what a run keeps in memory for replay is bounded:
:class:`BoundedTrajectoryRecorder` keeps at most :data:`MAX_REPLAY_SAMPLES` plant samples,
evenly spaced, however long the run.
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
from mbctl.sim.trajectory import TrajectoryRecorder

#: The most plant samples a run keeps for replay (``trajectory.npz``): 100,000 of the G1's qpos
#: are 29 MB (200 s of it at 500 Hz, every step). A longer run keeps every 2nd, 4th, 8th ... step
#: instead, evenly spaced, and its last state, so memory stays bounded (a one-hour G1 run keeps
#: every 32nd step, 64 ms apart: smooth at any replay speed up to real time); the CSV keeps every
#: control cycle.
MAX_REPLAY_SAMPLES = 100_000


class BoundedTrajectoryRecorder(TrajectoryRecorder):
    """A :class:`~mbctl.sim.trajectory.TrajectoryRecorder` that keeps at most ``max_samples`` samples.

    It keeps every ``stride``-th observed step, ``stride`` starting at 1; whenever the samples
    reach ``max_samples`` it drops every other one and doubles ``stride``. The samples stay evenly
    spaced in steps (the start and every ``stride``-th step), and ``close()`` adds the last state
    when it fell between two kept steps.

    Args:
        sim: The plant.
        folder: Where ``trajectory.npz`` and ``model.xml`` go.
        max_samples: The most samples kept (>= 2).

    Raises:
        ValueError: ``max_samples`` below 2.
    """

    def __init__(self, sim: Simulator, folder: Path, max_samples: int = MAX_REPLAY_SAMPLES):
        if max_samples < 2:
            raise ValueError(f"max_samples must be >= 2 (the start and the end); got {max_samples}")
        super().__init__(sim, folder)
        self.max_samples = max_samples
        self.stride = 1  #: observed steps per kept sample
        self.observed = 0  #: steps observed
        self._last_t = float(sim.data.time)
        self._last_qpos = sim.data.qpos.copy()

    def __call__(self, sim: Simulator) -> None:
        """Observer hook: keep the state if this step is a multiple of the stride."""
        self.observed += 1
        if self.observed % self.stride:
            self._last_t = float(self._data.time)
            np.copyto(self._last_qpos, self._qpos_now)
            return
        self._keep(self._data.time, self._qpos_now)
        if self._n == self.max_samples:  # every other sample, from the first: the start stays
            t, q = self._samples()
            self._replace_samples(t[::2].copy(), q[::2].copy())
            self.stride *= 2

    def close(self) -> Path:
        """Keep the last state (if it fell between kept steps), then write ``trajectory.npz``."""
        if not self._closed and self.observed % self.stride:
            self._keep(self._last_t, self._last_qpos)
        return super().close()


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
