"""The joint-limit acceleration bounds against their formula, on contiguous and scattered joints."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from mbctl.control.wbc import WBCConfig
from mbctl.control.wbc.joint_limits import JointLimitBounds


@pytest.mark.parametrize("every", [1, 2])  # every dof (a slice), every other one (an index array)
def test_bounds_are_the_stopping_formula_capped(tiny_biped, every):
    model = tiny_biped.pin_model
    actuated = np.arange(6, model.nv)[::every]
    limits = JointLimitBounds(model, actuated)
    assert len(limits) == len(actuated) and isinstance(limits.index, slice) == (every == 1)
    limits.configure(WBCConfig(joint_limit_horizon_s=0.2, joint_limit_margin_rad=0.05,
                               joint_limit_max_accel_rad_s2=30.0))
    rng = np.random.default_rng(5)
    q, v = pin.neutral(model), 3.0 * rng.standard_normal(model.nv)
    q[:3] = rng.standard_normal(3)  # (the free flyer's limits are infinite: no random configuration)
    q[7:] = rng.uniform(model.lowerPositionLimit[7:], model.upperPositionLimit[7:])
    lb, ub = np.full(model.nv + 4, -np.inf), np.full(model.nv + 4, np.inf)
    limits.write(np.concatenate([q, v]), lb, ub)
    T, reach = 0.2, q[limits.iq] + v[limits.iv] * 0.2
    lo = np.minimum((model.lowerPositionLimit[limits.iq] + 0.05 - reach) * 2.0 / T**2, 30.0)
    hi = np.maximum((model.upperPositionLimit[limits.iq] - 0.05 - reach) * 2.0 / T**2, -30.0)
    np.testing.assert_allclose(lb[limits.iv], lo, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(ub[limits.iv], hi, rtol=1e-12, atol=1e-9)
    others = np.setdiff1d(np.arange(len(lb)), limits.iv)
    assert np.all(lb[others] == -np.inf) and np.all(ub[others] == np.inf)
    assert np.all(lb[limits.iv] <= ub[limits.iv])  # capped on the far side: a range wider than 2 margins
