"""Size guards: inputs that would exhaust memory or run for hours are refused up front.

Each limit is a module constant with the reason it was chosen; :class:`SizeLimitError` names the
value, the limit and what to do instead. The figures were measured on this project's machine
(2 cores): Pinocchio's ``Data`` grows as about 66 bytes x nv^3 (0.23 GB at nv=150, 1.7 GB at 300),
MuJoCo's MJCF parser takes about 30 s for 20,000 bodies, a control-loop run keeps every cycle in
its CSV and at most 100,000 rows in memory and for replay (every Nth cycle of a longer run:
``mbctl.control.loop.MAX_LOG_ROWS``, ``mbctl.sim.recorder.MAX_REPLAY_SAMPLES``).
"""

from __future__ import annotations

from mbctl.exceptions import ToolkitError

#: Bodies in a model file (its includes counted): MuJoCo's parser needs ~30 s for 20,000.
MAX_BODIES = 2_000
#: Degrees of freedom of the robot's analytic model: Pinocchio's Data is ~66 B x nv^3 (0.23 GB).
MAX_ROBOT_DOF = 150
#: Simulated time of one run [s]: every control cycle is a CSV row and a qpos kept for replay
#: (600 s of the G1 at 500 Hz: 300,000 rows, ~0.5 GB of CSV).
MAX_DURATION_S = 600.0
#: Physics steps of one joint-step run (600 s at MuJoCo's default 2 ms timestep).
MAX_STEPS = 300_000
#: Random states of one cross-check (each state is both engines' M, bias, FK and Jacobians).
MAX_XCHECK_STATES = 100_000
#: Tasks of one sweep (each is a run folder); ``--force`` lifts it.
MAX_SWEEP_TASKS = 10_000
#: Samples per joint of the workspace plot (a samples^2 grid).
MAX_WORKSPACE_SAMPLES = 1_001


class SizeLimitError(ToolkitError):
    """An input over one of mbctl's size limits (see :mod:`mbctl.limits`)."""


def check_limit(what: str, value: float, limit: float, unit: str = "", advice: str = "") -> None:
    """SizeLimitError if ``value`` exceeds ``limit``; the message names both and the advice.

    Args:
        what: The input, as the user gave it (``--duration``).
        value: Its value.
        limit: The largest value accepted.
        unit: Unit text after the numbers (`` s``), or "".
        advice: What to do instead.
    """
    if value > limit:
        shown = f"{value:,}" if isinstance(value, int) else f"{value:,.6g}"
        raise SizeLimitError(f"{what} {shown}{unit} exceeds mbctl's limit of {limit:,.6g}{unit}"
                             + (f"; {advice}" if advice else ""))


def check_duration(duration_s: float | None, what: str = "--duration") -> None:
    """SizeLimitError if a run's simulated time is over :data:`MAX_DURATION_S` (None passes)."""
    if duration_s is not None:
        check_limit(what, duration_s, MAX_DURATION_S, " s",
                    "every control cycle is a CSV row and a sample kept for replay; run shorter pieces")
