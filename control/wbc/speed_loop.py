"""The walking speed loop: the footsteps' speed corrected, step by step, by the feet's measured speed.

The feet's midpoint moves (vx, vy) T per step when the steps land where planned; step adaptation
moves them off it, and a bias of the DCM (model error) would do so every step, so the walk would go
faster or slower than commanded. At each touchdown the loop integrates the difference over the last
step, ``c += speed_gain (v_command - v_measured)`` in the body frame, within
+-``max_speed_correction_m_s`` (:class:`~mbctl.control.wbc.walking_config.WalkingConfig`).

A step in which the DCM was more than ``speed_hold_after_m`` from its plan (a push), and the
two steps of its recovery after it (``SETTLE_STEPS``), are not integrated: the correction is then the
integral plus that step's own ``speed_gain`` times its error. Their footsteps went where the DCM
needed them; integrated, the push's speed (and the recovery's, back) wound the loop up, and it walked
the robot off sideways for steps after it had recovered.
"""

from __future__ import annotations

import math

import numpy as np

from mbctl.control.wbc.walking_config import WalkingConfig

#: The recovery's steps after a pushed one, which the loop does not integrate either [-].
SETTLE_STEPS = 2

#: Steps walked before the loop acts (the first ones start from standing) [-].
FIRST_STEPS = 3


class SpeedLoop:
    """The speed loop of one walk (see the module docstring).

    Args:
        config: The walking options (``speed_gain``, ``max_speed_correction_m_s``,
            ``speed_hold_after_m``).

    Attributes:
        correction: The correction (forward, sideways) [m/s], in the body frame, added to the
            command's speed.
    """

    def __init__(self, config: WalkingConfig):
        self.config = config
        self.reset()

    def reset(self) -> None:
        """No correction, nothing measured (a new walk)."""
        self.correction = np.zeros(2)
        self._integral = np.zeros(2)  # undisturbed steps only
        self._last: tuple[float, np.ndarray] | None = None  # the last touchdown's time [s] and midpoint
        self._pushed = False  # the DCM was speed_hold_after_m off its plan since the last touchdown
        self._settling = 0  # recovery steps still to come, not integrated

    @property
    def holding(self) -> bool:
        """Whether the next touchdown's step is one the loop does not integrate (pushed, or recovering)."""
        return self._pushed or self._settling > 0

    def watch(self, dcm_error_m: float) -> None:
        """Each cycle: the DCM's distance [m] from its plan."""
        if dcm_error_m > self.config.speed_hold_after_m:
            self._pushed = True

    def touchdown(self, t: float, mid_xy: np.ndarray, command_xy: tuple[float, float], heading_rad: float,
                  steps: int) -> None:
        """At a touchdown: the feet's midpoint (2,) [m] in W, the walk's command (body frame) [m/s]."""
        last, self._last = self._last, (t, mid_xy)
        pushed, self._pushed = self._pushed, False
        if pushed:
            self._settling = SETTLE_STEPS
        elif self._settling:
            self._settling -= 1
            pushed = True
        if last is None or steps < FIRST_STEPS or t <= last[0]:
            return
        c, s = math.cos(heading_rad), math.sin(heading_rad)
        d = (mid_xy - last[1]) / (t - last[0])
        measured = np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])
        cap = self.config.max_speed_correction_m_s
        step = self.config.speed_gain * (np.array(command_xy) - measured)
        if pushed:  # the step's own error, once
            self.correction = np.clip(self._integral + step, -cap, cap)
        else:
            self._integral = np.clip(self._integral + step, -cap, cap)
            self.correction = self._integral
