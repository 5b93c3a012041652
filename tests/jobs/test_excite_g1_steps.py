"""The excitation's steps: their times, their phases on the controller, and a stop that cuts one short.

The controller runs on a standing state held still (no physics): what is checked is the steps' own
logic, the contacts they switch and the targets they set.
"""

from __future__ import annotations

import numpy as np
import pytest

from mbctl.jobs.excite_g1_legs import SwingLegs
from mbctl.jobs.excite_g1_schedule import MIN_DURATION_FOR_STEPS_S, RAMP_S, step_starts
from mbctl.jobs.excite_g1_steps import LIFT_HEIGHT_M, MARKS_S, PRESS_M, STEP_TIMES_S, Steps, min_jerk
from mbctl.jobs.g1_wbc import g1_whole_body
from mbctl.robots.g1 import FEET, crouched_start
from mbctl.robots.interface import RobotState

DT = 0.002


def test_the_steps_come_one_after_the_other_after_the_ramp():
    total = sum(STEP_TIMES_S)
    assert step_starts(MIN_DURATION_FOR_STEPS_S - 0.1) == []
    for duration in (16.0, 30.0):
        (first, t1), (second, t2) = step_starts(duration)
        assert (first, second) == FEET
        assert t1 >= RAMP_S and t2 >= t1 + total and t2 + total <= duration
    assert step_starts(30.0) == [(FEET[0], 0.45 * 30 - total), (FEET[1], 0.8 * 30 - total)]


def test_the_minimum_jerk_rates_are_its_derivatives():
    h = 1e-6
    for t in (0.1, 0.7, 1.3):
        s, ds, dds = min_jerk(t, 1.5)
        assert ds == pytest.approx((min_jerk(t + h, 1.5)[0] - min_jerk(t - h, 1.5)[0]) / (2 * h), rel=1e-6)
        assert dds == pytest.approx((min_jerk(t + h, 1.5)[1] - min_jerk(t - h, 1.5)[1]) / (2 * h), rel=1e-5)
    assert min_jerk(-1.0, 1.5) == (0.0, 0.0, 0.0) and min_jerk(2.0, 1.5) == (1.0, 0.0, 0.0)


@pytest.fixture
def stepping(g1_torque):
    """A left step at t = 0 on the standing controller; run(t_end, stop_at) steps it and records."""
    wb = g1_whole_body(g1_torque)
    q = crouched_start(g1_torque)
    wb.hold(RobotState(q, np.zeros(g1_torque.nv), 0.0))
    ctrl = wb.controller
    steps = Steps(ctrl, ctrl.model, [(FEET[0], 0.0)], SwingLegs(ctrl.model, FEET))
    ground = ctrl.contacts[FEET[0]].X_WF0.translation.copy()

    def run(t_end: float, stop_at: float | None = None) -> dict[str, list]:
        rec: dict[str, list] = {"t": [], "s": [], "active": [], "target_weight": [], "z": [], "swing": []}
        for k in range(int(round(t_end / DT))):
            t = k * DT
            state = RobotState(q, np.zeros(g1_torque.nv), t)
            phase = steps.phase(t, state, stop_at if stop_at is not None and t >= stop_at else None)
            ctrl.compute(state)  # advances the contacts' force ramps
            contact = ctrl.contacts[FEET[0]]
            rec["t"].append(t)
            rec["s"].append(np.nan if phase is None else phase[1][0])
            rec["active"].append(contact.active)
            rec["target_weight"].append(contact.target_weight)
            free = steps.free.get(FEET[0])
            rec["z"].append(np.nan if free is None else free[0].translation[2] - ground[2])
            rec["swing"].append(any("swing" in task.name for task in ctrl.tasks))
        return {k: np.array(v) for k, v in rec.items()}

    return run


def test_a_step_releases_lifts_and_puts_its_foot_down(stepping):
    rec = stepping(MARKS_S[-1] + 0.1)
    t = rec["t"]
    assert not rec["active"][t > MARKS_S[0] + 0.31].all()  # released once the 0.3 s force ramp ended
    free = ~rec["active"]
    assert t[free][0] == pytest.approx(MARKS_S[0] + 0.3, abs=2 * DT)
    assert t[free][-1] == pytest.approx(MARKS_S[4], abs=2 * DT)  # put down when the lowering ends
    # the swing task is in the QP while the foot is free, from the cycle after its ramp ended
    assert np.flatnonzero(rec["swing"] != free).tolist() == [np.flatnonzero(free)[0]]
    held = (t >= MARKS_S[2]) & (t < MARKS_S[3])
    np.testing.assert_allclose(rec["z"][held], LIFT_HEIGHT_M, atol=1e-9)
    assert np.nanmin(rec["z"]) == pytest.approx(-PRESS_M, abs=1e-4)
    assert np.nanmax(rec["s"]) == 1.0 and rec["s"][t > MARKS_S[-1] - DT / 2][0] == pytest.approx(0, abs=1e-6)


@pytest.mark.parametrize("stop_at", [0.75, MARKS_S[0] + 0.1, MARKS_S[1] + 0.4])
def test_a_stop_cuts_the_step_short_without_a_jump(stepping, stop_at):
    rec = stepping(MARKS_S[-1] + 0.1, stop_at)
    t, s, z = rec["t"], rec["s"], rec["z"]
    ongoing = ~np.isnan(s)
    assert np.abs(np.diff(s[ongoing])).max() < 0.01  # the CoM reference turns back, it does not jump
    assert np.abs(np.diff(z[~np.isnan(z)])).max() < 1e-3 if not np.isnan(z).all() else True
    ended = t[ongoing][-1]
    assert ended < MARKS_S[-1] - 0.5  # the step ended early
    after = t >= stop_at
    if stop_at < MARKS_S[0]:  # before the release: the foot never lets go
        assert rec["active"].all() and (rec["target_weight"] == 1.0).all()
    elif stop_at < MARKS_S[0] + 0.3:  # while its force ramps out: loaded again, never freed
        assert rec["active"].all() and (rec["target_weight"][after] == 1.0).all()
    else:  # in the air: lowered from where it was, put down within the lowering's time
        down = t[after & rec["active"]][0]
        assert down - stop_at == pytest.approx(STEP_TIMES_S[4], abs=2 * DT)
        assert np.nanmin(z) == pytest.approx(-PRESS_M, abs=1e-4)
