"""Fourier excitations: at rest at the start, periodic, derivatives agree; the design and its limits."""

from __future__ import annotations

import re

import numpy as np
import pytest

from mbctl.planners.exceptions import InvalidPlanningInput
from mbctl.planners.excitation import ExcitationLimits, design_excitation
from mbctl.planners.fourier import FourierTrajectory


def _traj(seed=0, n=3, harmonics=4):
    rng = np.random.default_rng(seed)
    a, b = rng.standard_normal((2, n, harmonics))
    return FourierTrajectory.from_free(tuple(f"j{i}" for i in range(n)), rng.standard_normal(n), 5.0, a, b)


@pytest.mark.parametrize("seed", range(3))
def test_starts_at_rest_is_periodic_and_derivatives_agree(seed):
    traj = _traj(seed)
    q, v, a = traj.sample([0.0, traj.period_s])
    np.testing.assert_allclose(q[0], traj.q_start, atol=1e-12)
    np.testing.assert_allclose(v[0], 0.0, atol=1e-12)
    np.testing.assert_allclose(a[0], 0.0, atol=1e-12)
    np.testing.assert_allclose(q[1], q[0], atol=1e-9)  # one period later: the same state
    t = np.linspace(0.3, 4.0, 7)
    h = 1e-6
    qp, vp, _ = traj.sample(t + h)
    qm, vm, _ = traj.sample(t - h)
    _, v0, a0 = traj.sample(t)
    np.testing.assert_allclose((qp - qm) / (2 * h), v0, atol=1e-6)
    np.testing.assert_allclose((vp - vm) / (2 * h), a0, atol=1e-6)
    sampled = traj.trajectory(0.01, 2.0)
    assert sampled.names == traj.names and sampled.q.shape == (201, 3)


def test_coefficients_that_do_not_start_at_rest_are_refused():
    with pytest.raises(InvalidPlanningInput, match="do not start at rest"):
        FourierTrajectory(("a",), np.zeros(1), 2.0, np.ones((1, 2)), np.zeros((1, 2)))


def test_design_lowers_the_condition_number_within_the_limits(two_link_torque_gravity):
    robot = two_link_torque_gravity
    limits = ExcitationLimits(np.array([-1.0, -1.0]), np.array([1.0, 1.0]), np.array([2.0, 2.0]),
                              np.array([8.0, 4.0]))
    design = design_excitation(robot, ("shoulder", "elbow"), np.zeros(2), limits=limits, period_s=4.0,
                               harmonics=3, n_samples=30, max_iterations=15)
    assert design.condition_number < 0.5 * design.initial_condition_number
    assert design.structural_rank == 6
    q, v, _ = design.trajectory.sample(np.linspace(0, 4.0, 400))
    assert np.all(q >= -1.0 - 1e-9) and np.all(q <= 1.0 + 1e-9) and np.all(np.abs(v) <= 2.0 + 1e-6)
    assert np.all(design.limit_use <= 1.0 + 1e-9)


def test_bad_design_inputs_are_named(two_link_torque_gravity):
    weak = ExcitationLimits(-np.ones(2), np.ones(2), np.ones(2), np.array([4.0, 4.0]))  # g(0) needs 4.9 N m
    with pytest.raises(InvalidPlanningInput, match="joint 'shoulder' is already at its torque limit"):
        design_excitation(two_link_torque_gravity, ("shoulder", "elbow"), np.zeros(2), limits=weak)
    with pytest.raises(InvalidPlanningInput, match="q_max <= q_min at joint index 0"):
        ExcitationLimits(np.array([1.0]), np.array([0.0]), np.ones(1), np.ones(1))
    with pytest.raises(InvalidPlanningInput, match="at least one joint"):
        design_excitation(two_link_torque_gravity, (), np.zeros(2))



NARROW = """<mujoco><compiler angle="radian"/><worldbody><body name="a">
<joint name="j1" range="0 0.08" limited="true"/>
<inertial pos="0 0 0.1" mass="1" diaginertia="0.01 0.01 0.01"/>
<body name="b" pos="0 0 0.2"><joint name="j2" range="-1 1" limited="true"/>
<inertial pos="0 0 0.1" mass="1" diaginertia="0.01 0.01 0.01"/></body></body></worldbody>
<actuator><motor joint="j1" ctrlrange="-5 5"/><motor joint="j2" ctrlrange="-5 5"/></actuator></mujoco>"""


def test_a_joint_range_within_the_margins_is_named_not_indexed(tmp_path):
    from mbctl.robots.registry import load_robot

    (tmp_path / "narrow.xml").write_text(NARROW)
    robot = load_robot(tmp_path / "narrow.xml")
    with pytest.raises(InvalidPlanningInput, match=re.escape(
            "joint 'j1' has the range [0, 0.08] rad (0.08 rad wide); the excitation keeps 0.05 rad inside "
            "each limit, so it needs a range wider than 0.1 rad: widen the joint's range in the model or "
            "leave the joint out")):
        ExcitationLimits.from_robot(robot, ("j1", "j2"), np.zeros(2))
    with pytest.raises(InvalidPlanningInput, match=re.escape(
            "joint 'j2' starts at 0.98 rad, outside its range [-1, 1] rad less the excitation's 0.05 rad "
            "margins ([-0.95, 0.95] rad): start it inside")):
        ExcitationLimits.from_robot(robot, ("j2",), np.array([0.04, 0.98]))
    limits = ExcitationLimits.from_robot(robot, ("j1", "j2"), np.array([0.04, 0.0]), margin_rad=0.01)
    np.testing.assert_allclose([limits.q_min, limits.q_max], [[0.01, -0.99], [0.07, 0.99]])


def test_design_bounds_harmonics_and_its_grid(two_link_torque_gravity):
    robot, joints = two_link_torque_gravity, ("shoulder", "elbow")
    with pytest.raises(InvalidPlanningInput, match=re.escape(
            "harmonics must be 1 to 10 (more only slow the design; see MAX_HARMONICS); got 500")):
        design_excitation(robot, joints, np.zeros(2), harmonics=500)
    with pytest.raises(InvalidPlanningInput, match=re.escape(
            "n_samples must be >= 4 per harmonic (20 for 5); got 12")):
        design_excitation(robot, joints, np.zeros(2), harmonics=5, n_samples=12)
    with pytest.raises(InvalidPlanningInput, match=re.escape(
            "period_s must be a positive number of seconds; got -1.0")):
        design_excitation(robot, joints, np.zeros(2), period_s=-1.0)
