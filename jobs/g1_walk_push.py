"""Pushes while walking (``mbctl g1-walk push``): a force on the pelvis at a chosen gait phase, and after.

Each push is a horizontal force on the pelvis held ``hold_s`` (default :data:`PUSH_HOLD_S`; the force
is ``impulse / hold``), from a
direction in the world's x-y plane (0 deg = +x, the walk's start heading; 90 = +y, its left). The
first comes after :data:`FIRST_PUSH_S` of walking, the next :data:`PUSH_PERIOD_S` after the previous
one; each starts at the first control cycle, from then on, in its gait phase (:data:`PUSH_PHASES`):
``early`` and ``late`` single support (the cycle a swing passes 10 % or 60 % of its time: a due time
later in a swing waits for the next swing), ``double`` support (its first cycle from then on). The plant
applies it through :class:`~mbctl.sim.perturb.PushSchedule` (``xfrc_applied``), armed from the
control loop when the phase comes.

A push is ``survived`` when the G1 has not fallen :data:`PUSH_PERIOD_S` after it (or by the end of
the run); ``recovery_steps`` counts the touchdowns from the push until the DCM is back within
:data:`RECOVERED_M` of its plan (None if it never was).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

from mbctl.control.wbc import WalkingController
from mbctl.robots.g1 import PELVIS
from mbctl.sim.perturb import Push, PushSchedule

#: The gait phases a push may start in: (phase, fraction of the swing elapsed) or double support.
PUSH_PHASES = {"early": ("single", 0.1), "late": ("single", 0.6), "double": ("double", 0.0)}
#: The default time a push's force is held [s].
PUSH_HOLD_S = 0.1
FIRST_PUSH_S = 3.0
PUSH_PERIOD_S = 3.0
#: The DCM is back on its plan within this [m].
RECOVERED_M = 0.02


def pushes_duration_s(n: int) -> float:
    """The walk [s] that applies ``n`` pushes and judges the last (walking starts within 1 s)."""
    return FIRST_PUSH_S + n * PUSH_PERIOD_S + 1.0


@dataclass
class PushRecord:
    """One push and what followed (report values).

    Attributes:
        time_s: When it started [s].
        phase: The gait phase it started in.
        direction_deg: Its direction [deg] in the world's x-y plane.
        impulse_n_s: Its impulse [N s].
        hold_s: How long its force was held [s].
        force_n: Its force [N] (``impulse_n_s / hold_s``).
        survived: The G1 had not fallen ``PUSH_PERIOD_S`` after it (None while that is not known).
        recovery_steps: Touchdowns until the DCM was back within ``RECOVERED_M`` of its plan.
        max_dcm_error_m: The largest DCM error after it [m].
    """

    time_s: float
    phase: str
    direction_deg: float
    impulse_n_s: float
    hold_s: float
    force_n: float
    survived: bool | None = None
    recovery_steps: int | None = None
    max_dcm_error_m: float = 0.0
    _steps_at_push: int = field(default=0, repr=False)


class PhasePushes:
    """The pushes of a run, each armed when the walker reaches its gait phase (a sim perturbation).

    Args:
        model: The plant's MuJoCo model.
        walker: The walking controller (its gait phase arms the pushes).
        directions_deg: One push per direction [deg], in order.
        impulse_n_s: Each push's impulse [N s].
        phase: One of :data:`PUSH_PHASES`.
        hold_s: How long each push's force is held [s] (> 0; the force is ``impulse_n_s / hold_s``).
    """

    def __init__(self, model: mujoco.MjModel, walker: WalkingController, directions_deg: list[float],
                 impulse_n_s: float, phase: str, hold_s: float = PUSH_HOLD_S):
        self.model, self.walker = model, walker
        self.directions_deg, self.impulse_n_s, self.phase = list(directions_deg), impulse_n_s, phase
        self.hold_s = hold_s
        self._schedule: PushSchedule | None = None
        self.records: list[PushRecord] = []
        self.force_W = np.zeros(3)
        self._last_swing: tuple[object, float] | None = None  # the last cycle's swing and its phase

    def apply(self, data: mujoco.MjData) -> np.ndarray:
        """Apply the armed push at this physics step (the simulator calls this before each step)."""
        self.force_W = self._schedule.apply(data) if self._schedule is not None else np.zeros(3)
        return self.force_W

    def on_cycle(self, t_s: float, now_s: float, fallen: bool) -> None:
        """After each control cycle: arm the next push when its phase comes; score the last.

        Args:
            t_s: The time [s] of the state the cycle's command was computed from.
            now_s: The plant's time now [s] (a push starts then).
            fallen: The G1 has fallen.
        """
        status, gait = self.walker.status, self.walker.gait
        error = float(np.hypot(*(status.dcm - status.dcm_ref)))
        if self.records:
            last = self.records[-1]
            if t_s >= last.time_s + self.hold_s:
                last.max_dcm_error_m = max(last.max_dcm_error_m, error)
                if last.recovery_steps is None and error < RECOVERED_M and gait is not None:
                    last.recovery_steps = gait.steps - last._steps_at_push
            if last.survived is None and (fallen or t_s >= last.time_s + PUSH_PERIOD_S):
                last.survived = not fallen
        k = len(self.records)
        if k >= len(self.directions_deg) or gait is None or fallen:
            return
        due = FIRST_PUSH_S + k * PUSH_PERIOD_S + (gait.t0_s if gait is not None else 0.0)
        name, fraction = PUSH_PHASES[self.phase]
        swing, before = gait.swing, self._last_swing
        phase = swing.path.at(t_s).phase if swing is not None else None
        self._last_swing = (swing, phase) if phase is not None else None
        # single support: the cycle the swing's phase passes the fraction (not any cycle past it: a due
        # time late in a swing waits for the next one); double support: its first cycle from the due time
        crossed = phase is not None and phase >= fraction and (
            before is None or before[0] is not swing or before[1] < fraction)
        in_phase = status.phase == name and (name == "double" or crossed)
        if t_s < due or not in_phase:
            return
        angle = math.radians(self.directions_deg[k])
        force = self.impulse_n_s / self.hold_s
        force_W = (force * math.cos(angle), force * math.sin(angle), 0.0)
        self._schedule = PushSchedule(self.model, [Push(PELVIS, force_W, now_s, self.hold_s)])
        self.records.append(PushRecord(now_s, self.phase, self.directions_deg[k], self.impulse_n_s,
                                       self.hold_s, force, _steps_at_push=gait.steps))

    def values(self, fallen: bool) -> dict[str, Any]:
        """The report's push values (a push whose outcome is still open is scored now)."""
        for r in self.records:
            if r.survived is None:
                r.survived = not fallen
        pushes = [{k: v for k, v in r.__dict__.items() if not k.startswith("_")} for r in self.records]
        return {"pushes": pushes, "pushes_survived": sum(bool(r.survived) for r in self.records),
                "pushes_applied": len(self.records), "pushes_planned": len(self.directions_deg)}
