"""The excitation's swing legs: a reachable foot target is solved, an unreachable one is reported."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from mbctl.jobs.excite_g1_legs import LEG_IK_TOLERANCE, SwingLegs
from mbctl.robots.g1 import FEET, crouched_start


def test_a_lifted_foot_is_solved_and_an_unreachable_one_reported(g1):
    model, q = g1.pin_model, crouched_start(g1)
    legs = SwingLegs(model, FEET)
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    X_WF = pin.SE3(data.oMf[model.getFrameId(FEET[0])])
    lifted = pin.SE3(X_WF.rotation, X_WF.translation + [0.0, 0.0, 0.05])
    idx_q, q_leg = legs.solve(1.0, FEET[0], lifted, q)
    q_new = q.copy()
    q_new[idx_q] = q_leg
    pin.framesForwardKinematics(model, data, q_new)
    assert np.linalg.norm(data.oMf[model.getFrameId(FEET[0])].translation - lifted.translation) \
        <= LEG_IK_TOLERANCE.position_m
    assert legs.solves == 1 and not legs.failures and legs.line().endswith("all converged")
    legs.solve(2.0, FEET[1], pin.SE3(X_WF.rotation, X_WF.translation + [0.0, 0.0, 0.6]), q)
    assert legs.solves == 2 and len(legs.failures) == 1
    assert legs.section()["not_converged"] == 1 and legs.section()["first_failures"][0]["foot"] == FEET[1]
    assert "1 did NOT converge (first right_foot at t=2.00 s" in legs.line()
