"""The walking speed loop: it integrates undisturbed steps; a pushed step and its recovery act once each."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from mbctl.control.exceptions import WBCSetupError
from mbctl.control.wbc import WalkingConfig
from mbctl.control.wbc.speed_loop import FIRST_STEPS, SETTLE_STEPS, SpeedLoop
from tests.control.wbc.test_walking_push import _pushed, _to_first_touchdown

CONFIG = WalkingConfig()  # speed_gain 0.3, max_speed_correction_m_s 0.15, speed_hold_after_m 0.05
STEP_S = 0.6


def _walk(loop: SpeedLoop, speeds_x: list[float], errors_m: list[float],
          command=(0.3, 0.0)) -> list[np.ndarray]:
    """Touchdowns every STEP_S with the feet's midpoint moving ``speeds_x[k]`` [m/s] along x (heading 0),
    the DCM ``errors_m[k]`` off its plan during step k; the correction after each."""
    x, out = 0.0, []
    for k, (v, e) in enumerate(zip(speeds_x, errors_m, strict=True)):
        loop.watch(e)
        x += v * STEP_S
        loop.touchdown(STEP_S * (k + 1), np.array([x, 0.0]), command, 0.0, FIRST_STEPS + k)
        out.append(loop.correction.copy())
    return out


def test_undisturbed_steps_are_integrated_within_the_cap():
    corrections = _walk(SpeedLoop(CONFIG), [0.3, 0.2, 0.2, 0.2, 0.2, 0.2, 0.2], [0.01] * 7)
    # the first touchdown only starts the measurement; then 0.3 (0.3 - 0.2) = 0.03 m/s a step, capped at 0.15
    np.testing.assert_allclose([c[0] for c in corrections], [0.0, 0.03, 0.06, 0.09, 0.12, 0.15, 0.15],
                               atol=1e-12)
    np.testing.assert_allclose([c[1] for c in corrections], 0.0, atol=1e-12)


def test_a_pushed_step_and_its_recovery_act_once_each_and_integration_resumes():
    speeds = [0.3, 0.2, 0.2, -0.3, 0.6, 0.4, 0.2, 0.2]  # step 3 pushed backward, steps 4-5 recover
    errors = [0.01, 0.01, 0.01, 0.12, 0.04, 0.02, 0.01, 0.01]
    loop = SpeedLoop(CONFIG)
    corrections = _walk(loop, speeds, errors)
    integral = 0.06  # after steps 1 and 2 (0.03 each)
    expected = [0.0, 0.03, integral, integral + 0.3 * 0.6, integral + 0.3 * -0.3, integral + 0.3 * -0.1,
                integral + 0.03, integral + 0.06]
    expected[3] = min(expected[3], 0.15)  # the cap holds on the pushed step's correction too
    np.testing.assert_allclose([c[0] for c in corrections], expected, atol=1e-12)
    assert SETTLE_STEPS == 2  # (the two recovery steps above)
    assert not loop.holding
    # the loop before the hold (every step integrated) wound up on the push and the recovery
    # (capped at 0.15 on the push, it kept the recovery's errors: 0.03 of the bias correction lost after it)
    wound = _walk(SpeedLoop(replace(CONFIG, speed_hold_after_m=math.inf)), speeds, errors)
    np.testing.assert_allclose([c[0] for c in wound], [0.0, 0.03, 0.06, 0.15, 0.06, 0.03, 0.06, 0.09],
                               atol=1e-12)


def test_the_walker_holds_its_speed_loop_after_a_push(tiny_biped, crouch):
    walker, sim = _to_first_touchdown(tiny_biped, crouch)
    assert not walker.speed_loop.holding
    walker.compute(_pushed(sim.read_state(), 0.4))  # the DCM ~0.09 m off its plan
    assert np.linalg.norm(walker.status.dcm - walker.status.dcm_ref) > walker.config.speed_hold_after_m
    assert walker.speed_loop.holding
    walker.reset()
    assert not walker.speed_loop.holding


@pytest.mark.parametrize("value", [0.0, -0.01, math.nan])
def test_the_hold_is_checked(value):
    with pytest.raises(WBCSetupError, match="speed_hold_after_m"):
        WalkingConfig(speed_hold_after_m=value)
