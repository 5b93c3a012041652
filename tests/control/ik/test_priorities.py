"""Task priorities: the lexicographic solve, each level's residual, the setup errors."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from mbctl.control import IKSetupError
from mbctl.control.ik import DiffIK, MinkWholeBodyIK, WholeBodyIKConfig
from mbctl.control.tasks import ComTask, FramePositionTask, PostureTask, Tolerance
from mbctl.robots.g1 import FEET, KEYFRAME, PALM_SITES, PELVIS, with_palm_sites


def g1_config(**fields):
    """The G1 task set of ``mbctl ik``, from the G1's names."""
    return WholeBodyIKConfig(held_frames=FEET, target_frames=tuple(PALM_SITES), base_frame=PELVIS, com=True,
                             **fields)


def _conflicting_arm_tasks(model, q):
    """The 2-link end effector pulled to two different points: the levels decide which wins."""
    first, second = FramePositionTask("end_effector", model, name="first"), FramePositionTask(
        "end_effector", model, name="second")
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    p = data.oMf[model.getFrameId("end_effector")].translation
    first.set_target(p + [-0.05, -0.05, 0.0])  # both well inside the arm's reach
    second.set_target(p + [-0.15, 0.05, 0.0])
    posture = PostureTask(model, 1e-3)
    posture.set_target(q)
    return first, second, posture


@pytest.mark.parametrize("order", [(0, 1), (1, 0)])
def test_the_higher_level_wins_exactly_and_the_lower_one_is_reported(two_link, order):
    model = two_link.pin_model
    q0 = np.array([0.3, 0.9])
    first, second, posture = _conflicting_arm_tasks(model, q0)
    ik = DiffIK(model, [first, second, posture], damping=1e-9, levels=[*order, 1])
    res = ik.solve(q0, dt=1.0, tolerance=Tolerance(1e-9), max_iters=30, step_tol=1e-10)
    winner, loser = (first, second) if order == (0, 1) else (second, first)
    assert res.residuals[winner.name].position_m < 1e-8  # two dofs, one 2-D target: met exactly
    assert res.residuals[loser.name].position_m > 0.05  # the other one cannot be met as well
    assert res.levels == ((winner.name,), (loser.name, "posture"))
    assert res.level_residuals[0].position_m == pytest.approx(res.residuals[winner.name].position_m)
    assert res.level_residuals[1].position_m == pytest.approx(res.residuals[loser.name].position_m)
    # one weighted level ends in between: neither target is met
    weighted = DiffIK(model, [first, second, posture], damping=1e-9).solve(q0, dt=1.0, max_iters=30)
    assert weighted.residuals[winner.name].position_m > 0.01 and len(weighted.levels) == 1


def test_levels_are_checked(two_link):
    model = two_link.pin_model
    first, second, posture = _conflicting_arm_tasks(model, np.zeros(2))
    with pytest.raises(IKSetupError, match="without gaps; got \\[0, 2\\]"):
        DiffIK(model, [first, second, posture], levels=[0, 2, 2])
    with pytest.raises(IKSetupError, match="'posture' is a regulariser: it belongs to the last level"):
        DiffIK(model, [first, second, posture], levels=[0, 1, 0])
    with pytest.raises(IKSetupError, match="one non-negative integer per task"):
        DiffIK(model, [first, second, posture], levels=[0, 1])
    with pytest.raises(IKSetupError, match="Did you mean 'left_palm'"):
        g1_config(priorities=(("left_plam", 1),))
    with pytest.raises(IKSetupError, match="more than one priority"):
        g1_config(priorities=(("com", 0), ("com", 1)))


def test_config_levels_renumber_and_put_regularisers_last():
    cfg = g1_config(priorities=(("com", 2), ("left_palm", 5)), damping_cost=1e-3)
    # the tasks not named go one level below the lowest named one (6, renumbered 2)
    assert cfg.unnamed_level == 6
    assert cfg.levels == (("com",), ("left_palm",),
                          ("left_foot", "right_foot", "right_palm", "pelvis", "posture", "damping"))
    assert g1_config().levels == (g1_config().task_names,)


def test_mink_refuses_priorities(g1):
    robot = with_palm_sites(g1)
    with pytest.raises(IKSetupError, match="mink' solves one weighted level.*2 priority levels.*'qp'"):
        MinkWholeBodyIK(robot, g1_config(priorities=(("left_palm", 1),)), robot.keyframe_q(KEYFRAME))


def test_com_task_alone_at_level_0_with_a_target_at_level_1(two_link):
    """A CoM task (2-link: the arm's CoM in the plane) above a hand target: the CoM wins."""
    model = two_link.pin_model
    q0 = np.array([0.4, 0.8])
    com = ComTask([1.0, 1.0, 0.0])
    data = model.createData()
    pin.centerOfMass(model, data, q0)
    com.set_target(data.com[0] + [0.005, 0.0, 0.0])
    hand = FramePositionTask("end_effector", model)
    pin.framesForwardKinematics(model, data, q0)
    hand.set_target(data.oMf[model.getFrameId("end_effector")].translation + [0.0, 0.2, 0.0])
    res = DiffIK(model, [com, hand], damping=1e-9, levels=[0, 1]).solve(q0, tolerance=Tolerance(1e-9),
                                                                        max_iters=40, step_tol=1e-12)
    assert res.residuals["com"].position_m < 1e-8
    assert res.level_residuals[1].position_m > 0.01


def test_default_config_has_one_level():
    assert len(WholeBodyIKConfig(target_frames=("hand",)).levels) == 1
