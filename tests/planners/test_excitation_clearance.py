"""The excitation design keeps the arm off itself, and says which torque limits it had to assume."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mbctl.planners.excitation import (  # noqa: I001
    DEFAULT_EFFORT_N_M,
    SELF_CLEARANCE_M,
    ExcitationLimits,
    _self_pairs,
    design_excitation,
)
from mbctl.robots.collision import CollisionPair, closest_pairs, resolve_pairs
from mbctl.robots.registry import load_robot

#: A planar 3-link arm whose links collide with each other (not with their neighbours), started
#: folded so an excitation of +-1.2 rad per joint can swing the last link into the first; its
#: motors give no torque limit.
FOLD = (Path(__file__).parents[1] / "robots" / "assets" / "fold_arm.xml").read_text()


@pytest.fixture(scope="module")
def fold(tmp_path_factory):
    path = tmp_path_factory.mktemp("fold") / "fold.xml"
    path.write_text(FOLD)
    return load_robot(path)


@pytest.fixture(scope="module")
def design(fold):
    q0 = fold.keyframe_q("folded")
    return design_excitation(fold, ("j1", "j2", "j3"), q0, period_s=5.0, harmonics=5, seed=0)


def test_the_design_keeps_every_self_pair_clear(fold, design):
    """Measured independently (the collision layer's closest pair) on a grid 16x the design's."""
    assert design.self_pairs == ("g1/g3",)
    t = np.linspace(0.0, 5.0, 1280, endpoint=False)
    q = np.tile(fold.keyframe_q("folded"), (len(t), 1))
    q[:, :3] = design.trajectory.sample(t)[0]
    pairs = resolve_pairs(fold, [CollisionPair(("robot",), ("robot",))])
    distance = min(c.distance_m for c in closest_pairs(fold, q, pairs))
    assert distance >= 0.98 * SELF_CLEARANCE_M, distance
    assert design.min_clearance_m is not None and design.min_clearance_m >= SELF_CLEARANCE_M
    # the joints still use their range: the clearance did not freeze the arm
    assert design.limit_use[0] > 0.5 and design.condition_number < 100


def test_only_pairs_the_excited_joints_move_relative_to_each_other_are_kept(fold):
    q = fold.keyframe_q("folded")
    assert _self_pairs(fold, q, ("j2", "j3")).labels == ("g1/g3",)  # l1 stays, l3 moves
    assert _self_pairs(fold, q, ("j3",)).labels == ("g1/g3",)
    # j1 turns the whole arm: no pair moves relative to the other
    assert len(_self_pairs(fold, q, ("j1",))) == 0


def test_assumed_torque_limits_are_named(fold, design):
    assert design.limits is not None
    assert design.limits.defaulted_effort == ("j1", "j2", "j3")
    np.testing.assert_allclose(design.limits.tau_max, 0.5 * DEFAULT_EFFORT_N_M)


def test_a_robot_with_torque_limits_assumes_none(two_link_torque_gravity):
    limits = ExcitationLimits.from_robot(two_link_torque_gravity, ("shoulder", "elbow"),
                                         two_link_torque_gravity.neutral_q())
    assert limits.defaulted_effort == ()
    np.testing.assert_allclose(limits.tau_max, [15.0, 10.0])  # half of the motors' ctrlrange
