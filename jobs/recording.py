"""CSV rows of a control-loop run: named columns with units, the robot's full q for replay.

Every loop job streams one row per control cycle: time, the reference, the full configuration
(every joint, the floating base as position and quaternion, Pinocchio convention), the velocity,
the command, and job-specific extras. The full q makes every run replayable later.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from mbctl.robots.commands import Command
from mbctl.robots.interface import RobotState
from mbctl.robots.model_pair import Robot
from mbctl.robots.plant_kinematics import PlantKinematics
from mbctl.sim.recorder import CsvStream

_FREE_Q = ("x_m", "y_m", "z_m", "qx", "qy", "qz", "qw")
_FREE_V = ("vx_m_s", "vy_m_s", "vz_m_s", "wx_rad_s", "wy_rad_s", "wz_rad_s")


def _columns(robot: Robot, prefix: str, free: tuple[str, ...], slide: str, hinge: str) -> list[str]:
    cols: list[str] = []
    for j in robot.joints.values():
        if j.kind in ("free", "ball"):  # a ball joint has the rotational half of a free joint's
            cols += [f"{j.name}_{s}" for s in (free if j.kind == "free" else free[len(free) // 2:])]
        else:
            cols.append(f"{prefix}_{j.name}_{slide if j.kind == 'slide' else hinge}")
    return cols


def q_columns(robot: Robot) -> list[str]:
    """Column names of the full q (nq), Pinocchio convention.

    ``q_<joint>_rad`` (``_m`` for slides); free joints as ``<joint>_x_m … <joint>_qw``
    (quaternion x, y, z, w); ball joints as ``<joint>_qx … _qw``.
    """
    return _columns(robot, "q", _FREE_Q, "m", "rad")


def v_columns(robot: Robot) -> list[str]:
    """Column names of v (nv); free joints in the base frame (Pinocchio convention)."""
    return _columns(robot, "v", _FREE_V, "m_s", "rad_s")


Extra = Callable[[RobotState], Sequence[float]]


class LoopRows:
    """Streams control-loop cycles into a CSV: the ``on_step`` callback of ``control.loop.run``.

    Each row is assembled in one preallocated buffer (slices for the reference, q, v, command and
    extras) and handed to the stream, which copies it: no per-value Python work in the loop.

    Args:
        stream: The open CSV (created by :meth:`header` columns).
        reference_width: Entries of the reference position written per row (0: none).
        extra: Extra values per row from the state (their names are in the header).
        tick: Called once per row (the progress bar).
    """

    def __init__(self, stream: CsvStream, reference_width: int, extra: Extra | None = None,
                 tick: Callable[[], None] | None = None):
        self.stream = stream
        self.reference_width = reference_width
        self.extra = extra
        self.tick = tick
        self._row = np.empty(len(stream.header))
        self._slices: tuple[slice, slice, slice, slice, slice] | None = None

    @staticmethod
    def header(robot: Robot, reference_names: Sequence[str], command_names: Sequence[str],
               extra_names: Sequence[str] = ()) -> list[str]:
        """time_s, reference columns, full q, v, command columns, extras."""
        return ["time_s", *reference_names, *q_columns(robot), *v_columns(robot), *command_names,
                *extra_names]

    def _layout(self, state: RobotState, command: Command) -> tuple[slice, slice, slice, slice, slice]:
        """Where the reference, q, v, command and extras go in a row (from the first cycle's sizes)."""
        ends = np.cumsum([1, self.reference_width, state.q.size, state.v.size, command.values.size])
        n_extra = len(self._row) - int(ends[-1])
        if n_extra < 0 or (n_extra > 0) != (self.extra is not None):
            raise ValueError(
                f"{self.stream.path.name} has {len(self._row)} columns; a row has 1 time + "
                f"{self.reference_width} reference + {state.q.size} q + {state.v.size} v + "
                f"{command.values.size} command values{' + extras' if self.extra else ''}"
            )
        bounds = [int(e) for e in ends] + [len(self._row)]
        return tuple(slice(a, b) for a, b in zip(bounds[:-1], bounds[1:], strict=True))  # type: ignore[return-value]

    def __call__(self, k: int, state: RobotState, reference: Any, command: Command) -> None:
        """Write cycle ``k``'s row (the loop's ``on_step``)."""
        if self._slices is None:
            self._slices = self._layout(state, command)
        ref, q, v, cmd, extra = self._slices
        row = self._row
        row[0] = state.time_s
        if self.reference_width:
            row[ref] = reference[0]
        row[q] = state.q
        row[v] = state.v
        row[cmd] = command.values
        if self.extra is not None:
            row[extra] = self.extra(state)
        self.stream.write(row)
        if self.tick is not None:
            self.tick()


def command_columns(names: Sequence[str], unit: str) -> list[str]:
    """Command column names: ``tau_<name>_N_m`` for torques, ``target_<name>_rad`` for targets."""
    prefix = {"N_m": "tau", "rad": "target", "rad_s": "target_v"}.get(unit, "command")
    return [f"{prefix}_{n}_{unit}" for n in names]


class PlantSite:
    """A site's world position p_WS [m] computed by the *plant's* kinematics from a state's q.

    Uses MuJoCo's own kinematics on a scratch ``MjData`` (never the simulator's:
    :class:`~mbctl.robots.plant_kinematics.PlantKinematics`), so the measurement does not depend on
    the Pinocchio model a controller used.
    """

    def __init__(self, robot: Robot, site: str):
        self.robot = robot
        self._kinematics = PlantKinematics(robot=robot)
        self.sid = robot.site_id(site)

    def __call__(self, q: np.ndarray) -> np.ndarray:
        """p_WS (3,) [m] at configuration ``q`` (Pinocchio convention)."""
        return self._kinematics.at(q).site_xpos[self.sid].copy()

    def many(self, q_log: np.ndarray) -> np.ndarray:
        """p_WS (N, 3) [m] at each logged configuration (N, nq)."""
        return np.array([self(q) for q in q_log]).reshape(-1, 3)
