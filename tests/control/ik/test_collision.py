"""Collision avoidance in whole-body IK: the rows against finite differences, mink on the same pairs,
the step guard, and a target that cannot be reached without collision. Robots built in code."""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from mbctl.control import IKSetupError
from mbctl.control.ik import (
    CollisionAvoidanceLimit,
    MinkWholeBodyIK,
    QPWholeBodyIK,
    WholeBodyIKConfig,
)
from mbctl.control.ik import collision as collision_module
from mbctl.control.tasks import KinematicState, Tolerance
from mbctl.robots import load_robot
from mbctl.robots.collision import CollisionPair, pair_distances

#: A floating, rotated base (box) with a ball-jointed arm (capsule, then a hinge and a sphere hand)
#: and a hinged paddle (box) on the other side; the hand and the paddle can meet in front.
CRAB = """
<mujoco model="crab">
  <compiler angle="radian" autolimits="true"/>
  <worldbody>
    <body name="base" pos="0.1 -0.2 0.8" quat="0.9 0.1 0.3 0.2">
      <freejoint name="root"/>
      <geom name="base_box" type="box" size="0.12 0.08 0.05"/>
      <body name="arm" pos="0 0.12 0">
        <joint name="shoulder" type="ball"/>
        <geom name="arm_capsule" type="capsule" fromto="0 0 0 0.25 0 0" size="0.025"/>
        <body name="forearm" pos="0.25 0 0">
          <joint name="elbow" axis="0 0 1" range="-2.6 2.6"/>
          <geom name="forearm_capsule" type="capsule" fromto="0 0 0 0.2 0 0" size="0.02"/>
          <body name="hand" pos="0.2 0 0">
            <geom name="hand_sphere" type="sphere" size="0.04"/>
            <site name="palm" pos="0.02 0 0"/>
          </body>
        </body>
      </body>
      <body name="paddle" pos="0.2 -0.12 0">
        <joint name="paddle_hinge" axis="0 0 1" range="-1.5 1.5"/>
        <geom name="paddle_box" type="box" pos="0.1 0 0" size="0.1 0.01 0.06"/>
      </body>
    </body>
  </worldbody>
  <actuator><motor joint="elbow"/><motor joint="paddle_hinge"/></actuator>
</mujoco>
"""

PAIRS = (CollisionPair(("hand", "forearm"), ("paddle", "base")),)


@pytest.fixture(scope="module")
def crab(tmp_path_factory):
    path = tmp_path_factory.mktemp("crab") / "crab.xml"
    path.write_text(CRAB)
    return load_robot(path)


def _random_q(robot, seed):
    rng = np.random.default_rng(seed)
    q = pin.integrate(robot.pin_model, robot.neutral_q(), 0.8 * rng.standard_normal(robot.nv))
    q[:3] = [0.1, -0.2, 0.8]
    return q


def _distances(robot, pairs, q):
    data = mujoco.MjData(robot.mj_model)
    robot.plant_qpos(q, data.qpos)
    mujoco.mj_kinematics(robot.mj_model, data)
    return pair_distances(robot.mj_model, data, pairs.ids, distmax=10.0)


@pytest.mark.parametrize("seed", range(6))
def test_rows_are_minus_the_distance_rate_by_finite_differences(crab, seed):
    """Each row of a separated pair is ``-d'`` w.r.t. Pinocchio's tangent step.

    (For an overlapping pair, MuJoCo's witness points are contact points, as in mink; the row is
    then the rate along the contact normal, which need not be the penetration depth's gradient.)
    """
    limit = CollisionAvoidanceLimit(crab, PAIRS, detection_distance_m=10.0)
    q = _random_q(crab, seed)
    state = KinematicState(crab.pin_model, q)
    con = limit.compute_qp_inequalities(state, 1.0)
    assert con.G.shape == (len(limit.pairs), crab.nv)  # everything within 10 m: one row per pair
    h = 1e-7
    fd = np.column_stack([
        (_distances(crab, limit.pairs, pin.integrate(crab.pin_model, q, h * e))
         - _distances(crab, limit.pairs, pin.integrate(crab.pin_model, q, -h * e))) / (2 * h)
        for e in np.eye(crab.nv)])
    d = _distances(crab, limit.pairs, q)
    separated = d > 0.0
    assert separated.sum() >= 2
    np.testing.assert_allclose(-con.G[separated], fd[separated], atol=1e-6, rtol=0)
    np.testing.assert_allclose(con.h, 0.85 * np.maximum(d - 0.005, 0.0), atol=1e-12)


def test_a_changed_detection_distance_takes_effect(crab):
    """The broad phase and the queries follow ``detection_distance_m`` when it is reassigned."""
    limit = CollisionAvoidanceLimit(crab, PAIRS, detection_distance_m=10.0)
    q = _random_q(crab, 4)
    state = KinematicState(crab.pin_model, q)
    true = _distances(crab, limit.pairs, q)
    assert limit.compute_qp_inequalities(state, 1.0).G.shape[0] == len(limit.pairs)
    dmax = float(np.median(true))
    limit.detection_distance_m = dmax
    n_rows = limit.compute_qp_inequalities(state, 1.0).G.shape[0]
    assert n_rows == int(np.sum(true < dmax)) and 0 < n_rows < len(limit.pairs)
    np.testing.assert_allclose(limit.distances_m, np.minimum(true, dmax), atol=1e-9)


def test_coincident_witness_points_use_the_line_between_the_geoms_centres(crab):
    """Touching geoms (p1 = p2) take n along the centres' line, at the state's q even after the
    scratch data moved on (the guard measures other configurations in between)."""
    limit = CollisionAvoidanceLimit(crab, PAIRS, detection_distance_m=10.0)
    q = _random_q(crab, 2)
    state = KinematicState(crab.pin_model, q)
    idx, _, seg = limit._measure(q)
    seg[:, 3:] = seg[:, :3]  # (the measurement kept for q) every pair touching at its first point
    limit.sync(_random_q(crab, 3))  # the scratch data elsewhere
    G = limit.compute_qp_inequalities(state, 1.0).G
    data = mujoco.MjData(crab.mj_model)
    crab.plant_qpos(q, data.qpos)
    mujoco.mj_kinematics(crab.mj_model, data)
    g1, g2 = limit.pairs.ids[idx, 0], limit.pairs.ids[idx, 1]
    n = data.geom_xpos[g2] - data.geom_xpos[g1]
    n /= np.linalg.norm(n, axis=1)[:, None]
    n *= np.sign(limit.distances_m[idx])[:, None]
    assert np.isfinite(G).all() and G.shape == (len(idx), crab.nv)
    p = seg[:, :3]
    w = np.hstack([n, np.cross(p, n)])
    expected = (w @ state.data.J) * limit._dmask[idx]
    np.testing.assert_allclose(G, expected, atol=1e-12)


def test_the_broad_phase_keeps_the_same_pairs_by_the_incidence_product_and_by_gathering(crab, monkeypatch):
    """The pairs' centre differences as one product with their incidence matrix (small pair sets)
    and by gathering the geoms' centres (large ones) keep the same candidates."""
    by_product = CollisionAvoidanceLimit(crab, PAIRS, detection_distance_m=0.1)
    monkeypatch.setattr(collision_module, "INCIDENCE_MAX", 0)
    by_gather = CollisionAvoidanceLimit(crab, PAIRS, detection_distance_m=0.1)
    assert by_product._incidence is not None and by_gather._incidence is None
    counts = set()
    for seed in range(12):
        q = _random_q(crab, seed)
        by_product.sync(q)
        by_gather.sync(q)
        np.testing.assert_array_equal(by_product.candidates(), by_gather.candidates())
        counts.add(len(by_product.candidates()))
    assert len(counts) > 1  # the configurations keep different numbers of pairs


def test_mink_gets_the_same_pairs_and_the_same_rows(crab):
    """mink's CollisionAvoidanceLimit on our pairs: the same set, and the same distance rate for
    any step once the two velocity conventions are converted (MuJoCo's free joint is world-linear)."""
    cfg = WholeBodyIKConfig(target_frames=("palm",), collision_pairs=PAIRS,
                            collision_detection_distance_m=10.0)
    q = _random_q(crab, 7)
    ours, theirs = QPWholeBodyIK(crab, cfg, q), MinkWholeBodyIK(crab, cfg, q)
    assert set(theirs.collision_limit.geom_id_pairs) == {tuple(p) for p in ours.collision_pairs.ids.tolist()}
    ours.update(q)
    theirs.update(q)
    G_ours = ours.collision_limit.compute_qp_inequalities(ours.state, 1.0).G
    mink_con = theirs.collision_limit.compute_qp_inequalities(theirs.configuration, 1.0)
    order = [theirs.collision_limit.geom_id_pairs.index(tuple(p)) for p in ours.collision_pairs.ids.tolist()]
    v = np.random.default_rng(0).standard_normal(crab.nv)
    v_mj = crab.converter.v_pin_to_mj(q, v)
    np.testing.assert_allclose(G_ours @ v, mink_con.G[order] @ v_mj, atol=1e-9)
    np.testing.assert_allclose(ours.collision_limit.compute_qp_inequalities(ours.state, 1.0).h,
                               mink_con.h[order], atol=1e-12)


def _hand_into_the_base(robot, backend):
    q0 = robot.neutral_q()
    q0[:3] = [0.1, -0.2, 0.8]
    cfg = WholeBodyIKConfig(held_frames=("base",), target_frames=("palm",), collision_pairs=PAIRS,
                            min_distance_m=0.01, joint_max_velocity=0.5)
    ik = backend(robot, cfg, q0)
    # a target inside the (held) base box: the hand can only come as close as the limit allows
    X = robot.pin_model.createData()
    pin.framesForwardKinematics(robot.pin_model, X, q0)
    base = X.oMf[robot.pin_model.getFrameId("base")]
    ik.set_target_position("palm", base.act(np.array([0.05, 0.0, 0.0])))
    return ik, q0


def test_a_target_inside_the_body_stops_at_the_minimum_distance(crab):
    ik, q0 = _hand_into_the_base(crab, QPWholeBodyIK)
    res = ik.solve(q0, Tolerance(1e-3), max_iters=100)
    assert not res.converged
    d = np.array([_distances(crab, ik.collision_pairs, q).min() for q in res.q_path])
    assert d.min() >= 0.01 - 1e-9, d  # every step, as MuJoCo measures it
    assert d[-1] < 0.012  # it went as close as it was allowed
    assert res.residuals["palm"].position_m > 0.05


def test_the_guard_halves_a_step_that_would_jump_through(crab):
    """A step the linearisation allows (the pair is beyond the detection distance) but that ends
    inside the paddle is shortened until the pair is clear again."""
    limit = CollisionAvoidanceLimit(crab, PAIRS, min_distance_m=0.01, detection_distance_m=0.02)
    q = crab.neutral_q()
    q[:3] = [0.1, -0.2, 0.8]
    elbow = crab.joint("elbow").idx_v
    dq = np.zeros(crab.nv)
    dq[elbow] = -2.4  # swings the forearm through the paddle
    d_end = _distances(crab, limit.pairs, pin.integrate(crab.pin_model, q, dq)).min()
    assert d_end < 0.0
    safe = limit.guard_step(crab.pin_model, q, dq)
    assert 0.0 < np.max(np.abs(safe)) < 2.4 and np.allclose(safe / np.max(np.abs(safe)), dq / 2.4)
    assert _distances(crab, limit.pairs, pin.integrate(crab.pin_model, q, safe)).min() >= 0.01


def test_bad_collision_settings_are_refused(crab):
    with pytest.raises(IKSetupError, match="detection distance .* must exceed the minimum distance"):
        WholeBodyIKConfig(target_frames=("palm",), collision_pairs=PAIRS, min_distance_m=0.2)
    with pytest.raises(IKSetupError, match="gain must be in"):
        CollisionAvoidanceLimit(crab, PAIRS, gain=0.0)
    with pytest.raises(IKSetupError, match="Did you mean 'paddle'"):
        QPWholeBodyIK(crab, WholeBodyIKConfig(target_frames=("palm",), collision_pairs=(
            CollisionPair(("padle",), ("hand",)),)), crab.neutral_q())
