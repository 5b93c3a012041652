"""The cross-check reads Pinocchio's outputs through views into its data, made once.

``frames.joint_placements_view`` aliases Pinocchio's memory (all joint placements in one view);
the evaluator also holds views of ``computeAllTerms``'s matrices. These tests hold the placements
view to Pinocchio's own placements state by state, and the evaluator without the views (reading
Pinocchio's attributes per state) to the same results bit for bit.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from mbctl.robots import load_robot
from mbctl.robots.crosscheck import evaluator as evaluator_module
from mbctl.robots.crosscheck.evaluator import Evaluator
from mbctl.robots.crosscheck.frames import joint_placements_view, match_frames
from mbctl.robots.crosscheck.plant import comparison_model
from mbctl.robots.crosscheck.sampling import sample_states


@pytest.fixture(params=["g1", "leg"])
def robot(request, asset):
    if request.param == "g1":
        return request.getfixturevalue("g1")
    return load_robot(asset("ball_free_leg.xml"), check=False)


def test_the_view_follows_data_omi_state_by_state(robot):
    pm = robot.pin_model
    pd = pm.createData()
    view = joint_placements_view(pd)
    assert view is not None and view.shape == (pm.njoints, 4, 3) and not view.flags.writeable
    states = sample_states(robot, 4, 1)
    for q, v in zip(states.q, states.v, strict=True):
        pin.computeAllTerms(pm, pd, q, v)
        for j, X in enumerate(pd.oMi.tolist()):
            np.testing.assert_array_equal(view[j, :3].T, X.rotation)
            np.testing.assert_array_equal(view[j, 3], X.translation)


def test_without_the_views_the_results_are_the_same(robot, monkeypatch):
    m, _ = comparison_model(robot.mj_model, robot.scene_body_ids)
    frames, states = match_frames(robot), sample_states(robot, 12, 3)
    with_view = Evaluator(robot, m, frames, 5).run(states)
    outputs = evaluator_module._pin_outputs
    monkeypatch.setattr(evaluator_module, "joint_placements_view", lambda data: None)
    monkeypatch.setattr(evaluator_module, "_pin_outputs", lambda pd: tuple(np.array(x) for x in outputs(pd)))
    evaluator = Evaluator(robot, m, frames, 5)
    assert evaluator._oMi is None and evaluator._pd_views is None
    without = evaluator.run(states)
    for name, (err, scale) in with_view.items():
        np.testing.assert_array_equal(without[name][0], err)
        assert without[name][1] == scale
