"""Keep MuJoCo's log file out of the user's working directory.

MuJoCo's default log handler appends every warning and error to ``MUJOCO_LOG.TXT`` in the current
directory (a NaN state during a run is enough). mbctl reports MuJoCo's warnings itself (the
simulator's warning counters, :class:`~mbctl.sim.exceptions.SimulationDiverged`, the run report),
so on import it switches that file off through MuJoCo's own log configuration
(``mujoco.MjLogConfig``, MuJoCo 4); the console line stays. A log file the user configured
elsewhere (another ``logfile``) is left alone.
"""

from __future__ import annotations

import mujoco

#: MuJoCo's default log file, relative to the working directory.
DEFAULT_LOG_FILE = "MUJOCO_LOG.TXT"


def keep_log_out_of_cwd() -> None:
    """Turn off MuJoCo's log file while it points at ``MUJOCO_LOG.TXT`` in the working directory."""
    config = mujoco.MjLogConfig.get()
    if config.logto_file and config.logfile == DEFAULT_LOG_FILE:
        config.logto_file = False
        config.set()


keep_log_out_of_cwd()
