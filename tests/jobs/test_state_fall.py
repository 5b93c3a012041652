"""The G1's fall rule on the controller's own state (over DDS): the first fall kept, its time and source."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from mbctl.jobs.state_fall import StateFallWatch
from mbctl.robots.g1 import FALL_HEIGHT_M
from mbctl.robots.interface import RobotState


def _state(z_m: float, t_s: float) -> RobotState:
    q = np.zeros(36)
    q[2], q[6] = z_m, 1.0
    return RobotState(q, np.zeros(35), t_s)


def test_the_first_state_below_the_fall_height_ends_the_run_and_is_kept():
    watch = StateFallWatch()
    assert not watch.check(_state(0.72, 0.0)) and not watch.check(_state(FALL_HEIGHT_M, 0.002))
    assert watch.reason is None and watch.time_s is None
    assert watch.check(_state(0.42, 1.25))
    assert watch.check(_state(0.75, 1.5))  # a later state higher up does not undo it
    assert watch.reason == "pelvis at 0.420 m (below 0.5 m) (estimated state)" and watch.time_s == 1.25


def test_the_reports_fall_keys_say_whose_verdict_they_are():
    watch = StateFallWatch()
    assert watch.values(None) == {"fell": False, "fall_reason": None, "fall_time_s": None,
                                  "fall_source": "estimated state"}
    watch.check(_state(0.3, 2.0))
    assert watch.values(None)["fell"] is True and watch.values(None)["fall_time_s"] == 2.0
    plant = SimpleNamespace(fall_reason="torso_link touched the floor", fall_time_s=1.5)
    assert watch.values(plant) == {  # type: ignore[arg-type]  # the monitor's two fields
        "fell": True, "fall_reason": "torso_link touched the floor", "fall_time_s": 1.5,
        "fall_source": "plant"}
    assert watch.truth_values(False) == {"fell": False, "fall_reason": None, "fall_time_s": None,
                                         "fall_source": "truth log"}
    assert watch.truth_values(True) == {"fell": True, "fall_time_s": 2.0, "fall_source": "truth log",
                                        "fall_reason": "pelvis below its fall height (truth log)"}
