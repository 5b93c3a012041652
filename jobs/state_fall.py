"""The G1's fall rule on the controller's own state, where the plant is not observed (over DDS).

In-process the plant's monitor says when the robot fell and ends the run; after a DDS run the
bridge's truth log says it (``--truth``). During a DDS run, and on a robot where no truth log
exists, the client's only view is its state: the base from the estimator (the IMU's orientation
and the legs' kinematics from the stance foot). A whole-body controller left commanding a robot
that lies on the floor is what the end of a run prevents (the damping command every period), so
the run ends once that state's pelvis is below the fall height; the truth log, when given, has
the last word on the verdict.
"""

from __future__ import annotations

from typing import Any

from mbctl.robots.g1 import G1_FALL
from mbctl.robots.interface import RobotState
from mbctl.sim.monitor import PlantMonitor

#: What the reason says after the rule's words.
SOURCE = "(estimated state)"


class StateFallWatch:
    """The G1's fall rule (:data:`~mbctl.robots.g1.G1_FALL`: the pelvis height) on each cycle's state.

    Attributes:
        reason: Why the robot fell, by its state (None while it has not).
        time_s: The state's time [s] when it first did (None before).
    """

    def __init__(self) -> None:
        self.reason: str | None = None
        self.time_s: float | None = None

    def check(self, state: RobotState) -> bool:
        """Whether the robot has fallen by ``state`` or an earlier one (the pelvis ``q[2]`` [m] in W)."""
        if self.reason is None:
            reason = G1_FALL.reason(float(state.q[2]), ())
            if reason is not None:
                self.reason, self.time_s = f"{reason} {SOURCE}", float(state.time_s)
        return self.reason is not None

    def values(self, monitor: PlantMonitor | None) -> dict[str, Any]:
        """The report's fall keys: the plant monitor's verdict in-process, else this one's."""
        if monitor is not None:
            return {"fell": monitor.fall_reason is not None, "fall_reason": monitor.fall_reason,
                    "fall_time_s": monitor.fall_time_s, "fall_source": "plant"}
        return {"fell": self.reason is not None, "fall_reason": self.reason, "fall_time_s": self.time_s,
                "fall_source": "estimated state"}

    def truth_values(self, fell: bool) -> dict[str, Any]:
        """The report's fall keys from the bridge's truth log, which has the last word.

        The time is this watch's, when it saw the fall too (the truth check gives none).
        """
        return {"fell": fell, "fall_reason": "pelvis below its fall height (truth log)" if fell else None,
                "fall_time_s": self.time_s if fell else None, "fall_source": "truth log"}
