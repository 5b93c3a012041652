"""The Pinocchio <-> MuJoCo convention conversions, checked against both engines."""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from mbctl.robots import StateError, quat_wxyz_to_xyzw, quat_xyzw_to_wxyz, quat_xyzw_yaw
from mbctl.robots.conventions import rotation_from_quat_xyzw

finite = st.floats(-1e3, 1e3, allow_nan=False)


@given(arrays(float, 4, elements=finite))
def test_quaternion_reorder_round_trip(q):
    np.testing.assert_array_equal(quat_xyzw_to_wxyz(quat_wxyz_to_xyzw(q)), q)
    assert quat_wxyz_to_xyzw(q)[3] == q[0]


@settings(max_examples=50, deadline=None)
@given(arrays(float, 4, elements=st.floats(-1, 1)).filter(lambda q: np.linalg.norm(q) > 0.1))
def test_rotation_matches_pinocchio(q_xyzw):
    q_xyzw = q_xyzw / np.linalg.norm(q_xyzw)
    R_pin = pin.Quaternion(q_xyzw[3], *q_xyzw[:3]).toRotationMatrix()
    np.testing.assert_allclose(rotation_from_quat_xyzw(q_xyzw), R_pin, atol=1e-14)


def random_state(robot, rng):
    q = pin.randomConfiguration(
        robot.pin_model, -np.ones(robot.nq), np.ones(robot.nq)
    ) if robot.has_floating_base else rng.uniform(-1, 1, robot.nq)
    if robot.has_floating_base:
        q[:3] = rng.uniform(-1, 1, 3)
        quat = rng.normal(size=4)
        q[3:7] = quat / np.linalg.norm(quat)
    return q, rng.normal(size=robot.nv)


def test_configuration_round_trip_g1(g1):
    rng = np.random.default_rng(0)
    q, _ = random_state(g1, rng)
    q_mj = g1.converter.q_pin_to_mj(q)
    np.testing.assert_array_equal(q_mj[3:7], quat_xyzw_to_wxyz(q[3:7]))
    np.testing.assert_array_equal(g1.converter.q_mj_to_pin(q_mj), q)


def test_velocity_map_matches_mujoco_integration_g1(g1):
    """v_pin is the tangent Pinocchio sees of MuJoCo's motion under v_mj = T(q) v_pin."""
    rng = np.random.default_rng(1)
    q, v = random_state(g1, rng)
    conv = g1.converter
    q_mj = conv.q_pin_to_mj(q)
    v_mj = conv.v_pin_to_mj(q, v)
    dt = 1e-7
    q_mj_next = q_mj.copy()
    mujoco.mj_integratePos(g1.mj_model, q_mj_next, v_mj, dt)
    v_fd = pin.difference(g1.pin_model, q, conv.q_mj_to_pin(q_mj_next)) / dt
    np.testing.assert_allclose(v_fd, v, atol=1e-5)
    np.testing.assert_allclose(conv.v_mj_to_pin(q, v_mj), v, atol=1e-14)


def test_mass_matrix_and_bias_conversion_g1(g1):
    """M and b from MuJoCo, converted, equal Pinocchio's (the Tdot v term included)."""
    rng = np.random.default_rng(2)
    m = g1.mj_model
    d = mujoco.MjData(m)
    pd = g1.pin_model.createData()
    for _ in range(3):
        q, v = random_state(g1, rng)
        d.qpos[:] = g1.converter.q_pin_to_mj(q)
        d.qvel[:] = g1.converter.v_pin_to_mj(q, v)
        mujoco.mj_forward(m, d)
        M_mj = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, d, M_mj)
        M_pin = pin.crba(g1.pin_model, pd, q)
        M_pin = np.triu(M_pin) + np.triu(M_pin, 1).T
        np.testing.assert_allclose(g1.converter.mass_matrix_mj_to_pin(q, M_mj), M_pin, atol=1e-10)
        b_pin = pin.nonLinearEffects(g1.pin_model, pd, q, v)
        b_conv = g1.converter.bias_mj_to_pin(q, v, M_mj, d.qfrc_bias)
        np.testing.assert_allclose(b_conv, b_pin, atol=1e-9)
        # without the Tdot v term the free-flyer rows disagree: the term is needed
        b_naive = g1.converter.force_mj_to_pin(q, d.qfrc_bias)
        assert np.max(np.abs(b_naive - b_pin)) > 1e-3


def test_acceleration_round_trip_g1(g1):
    rng = np.random.default_rng(3)
    q, v = random_state(g1, rng)
    a = rng.normal(size=g1.nv)
    conv = g1.converter
    np.testing.assert_allclose(conv.a_mj_to_pin(q, v, conv.a_pin_to_mj(q, v, a)), a, atol=1e-12)


def test_two_link_is_identity(two_link):
    conv = two_link.converter
    assert not conv.has_quaternions
    q = np.array([0.3, -1.2])
    np.testing.assert_array_equal(conv.q_pin_to_mj(q), q)
    np.testing.assert_array_equal(conv.v_pin_to_mj(q, q), q)


@pytest.mark.parametrize(
    "value, message",
    [
        ([1.0, 2.0, 3.0], r"q must have shape \(2,\); got shape \(3,\)"),
        ([1.0, np.nan], r"q must be finite; entries \[1\] are \[nan\]"),
        ("ab", "q must be a numeric vector of shape"),
    ],
)
def test_bad_state_vectors_are_named(two_link, value, message):
    with pytest.raises(StateError, match=message):
        two_link.converter.check_q(value)


def test_batched_velocity_maps_match_the_per_state_conversions(g1):
    """VelocityMaps (the cross-check's batches) against the per-state methods, state by state."""
    rng = np.random.default_rng(4)
    states = [random_state(g1, rng) for _ in range(5)]
    q, v = np.array([s[0] for s in states]), np.array([s[1] for s in states])
    x, J = rng.normal(size=v.shape), rng.normal(size=(5, 4, 6, g1.nv))
    M = rng.normal(size=(5, g1.nv, g1.nv))
    conv = g1.converter
    maps = conv.velocity_maps(q)
    np.testing.assert_array_equal(conv.qs_pin_to_mj(q)[2], conv.q_pin_to_mj(q[2]))
    to_mj, dot_v = maps.to_mj(x), maps.dot_v(v)
    to_pin, right, congruence = maps.to_pin(x.copy()), maps.right(J.copy()), maps.congruence(M.copy())
    for k in range(5):
        T = conv.velocity_map(q[k])
        np.testing.assert_allclose(to_mj[k], conv.v_pin_to_mj(q[k], x[k]), atol=1e-14)
        np.testing.assert_allclose(to_pin[k], conv.v_mj_to_pin(q[k], x[k]), atol=1e-14)
        np.testing.assert_allclose(dot_v[k], conv.velocity_map_dot_v(q[k], v[k]), atol=1e-14)
        np.testing.assert_allclose(right[k], J[k] @ T, atol=1e-14)
        np.testing.assert_allclose(congruence[k], T.T @ M[k] @ T, atol=1e-13)
    # packed: the free joint's x, y, z columns of 4 frames first, then two other entries
    iv = conv.free_v[0]
    frames = np.r_[np.tile(np.arange(4), 3), 0, 2]
    cols = np.r_[np.repeat([iv, iv + 1, iv + 2], 4), 10, 20]
    packed = maps.right_packed(J[:, :, :, :].transpose(0, 2, 1, 3)[:, :, frames, cols].copy(), [(0, 4)])
    np.testing.assert_allclose(packed, right.transpose(0, 2, 1, 3)[:, :, frames, cols], atol=1e-14)


@settings(max_examples=50)
@given(arrays(float, (6, 4), elements=st.floats(-1.0, 1.0)))
def test_quat_xyzw_yaw_is_pinocchio_s_rpy_yaw_for_one_and_for_rows(raw):
    quats = raw[np.linalg.norm(raw, axis=1) > 0.1]
    quats = quats / np.linalg.norm(quats, axis=1, keepdims=True)
    expected = [pin.rpy.matrixToRpy(pin.Quaternion(w, x, y, z).matrix())[2] for x, y, z, w in quats]
    got = [quat_xyzw_yaw(q) for q in quats]
    assert all(isinstance(g, float) for g in got)
    # matrixToRpy picks the other of its two solutions only at pitch +-90 deg, where yaw is undefined
    pitch = [pin.rpy.matrixToRpy(pin.Quaternion(w, x, y, z).matrix())[1] for x, y, z, w in quats]
    regular = np.abs(np.cos(pitch)) > 1e-3
    np.testing.assert_allclose(np.array(got)[regular], np.array(expected)[regular], atol=1e-9)
    np.testing.assert_allclose(quat_xyzw_yaw(quats), np.array(got), rtol=0, atol=1e-15)
