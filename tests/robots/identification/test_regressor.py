"""The identification equations: regressor times parameters is Pinocchio's RNEA, contacts projected out."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from mbctl.robots.identification.parameters import COULOMB_SMOOTHING_RAD_S, ParameterSet
from mbctl.robots.identification.regressor import SampleEquations, stack
from mbctl.robots.identification.samples import Samples
from mbctl.robots.registry import load_robot

#: A 6-DoF arm built in code: unaligned and offset joint axes, joint anchors away from the body
#: origin, full inertias, a welded tool body and a massless intermediate joint body.
SIX_DOF = """
<mujoco model="six_dof">
  <compiler angle="radian" autolimits="true" inertiafromgeom="false"/>
  <option gravity="0.3 -0.2 -9.81"/>
  <worldbody>
    <body name="base" pos="0.1 0 0.2" quat="0.9 0.1 0 0.2">
      <joint name="j1" axis="0 0 1" pos="0 0 0.02" armature="0.01" damping="0.2" frictionloss="0.1"/>
      <inertial pos="0.01 0.02 0.05" mass="2.0" fullinertia="0.02 0.03 0.025 0.001 -0.002 0.0015"/>
      <body name="upper" pos="0 0.05 0.1">
        <joint name="j2" axis="0 1 0" armature="0.02"/>
        <inertial pos="0.15 0 0.01" quat="0.95 0 0.3 0" mass="1.5" diaginertia="0.004 0.02 0.021"/>
        <body name="fore" pos="0.3 0 0">
          <joint name="j3" axis="0 0.6 0.8" pos="0.01 0 0"/>
          <inertial pos="0.12 0.01 0" mass="1.0" diaginertia="0.002 0.01 0.011"/>
          <body name="wrist" pos="0.25 0 0">
            <joint name="j4" axis="1 0 0"/>
            <joint name="j5" axis="0 1 0" pos="0.02 0 0"/>
            <inertial pos="0.03 0 0" mass="0.4" diaginertia="0.0005 0.0006 0.0007"/>
            <body name="flange" pos="0.05 0 0">
              <joint name="j6" type="slide" axis="1 0 0" range="-0.1 0.1"/>
              <inertial pos="0.01 0.005 0" mass="0.2" diaginertia="0.0001 0.0002 0.0002"/>
              <body name="tool" pos="0.04 0 0.01" euler="0 0.3 0">
                <inertial pos="0.02 0 0.01" mass="0.3" diaginertia="0.0003 0.0004 0.0005"/>
              </body>
            </body>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor joint="j1"/><motor joint="j2"/><motor joint="j3"/><motor joint="j4"/><motor joint="j5"/>
    <motor joint="j6"/>
  </actuator>
</mujoco>
"""


@pytest.fixture(scope="module")
def six_dof(tmp_path_factory):
    path = tmp_path_factory.mktemp("six_dof") / "six_dof.xml"
    path.write_text(SIX_DOF)
    return load_robot(path)


def _states(robot, n, seed):
    model = robot.pin_model
    rng = np.random.default_rng(seed)
    lo = np.where(np.isfinite(model.lowerPositionLimit), model.lowerPositionLimit, -np.pi).clip(-3, 3)
    hi = np.where(np.isfinite(model.upperPositionLimit), model.upperPositionLimit, np.pi).clip(-3, 3)
    for _ in range(n):
        q = pin.randomConfiguration(model, lo, hi)
        yield q, rng.standard_normal(model.nv), rng.standard_normal(model.nv)


def _check_regressor(robot, tol=1e-10):
    params = ParameterSet(robot, friction=True, armature=True)
    model, data = robot.pin_model, robot.pin_model.createData()
    fc = np.asarray(model.upperDryFrictionLimit)
    worst = 0.0
    for q, v, a in _states(robot, 20, 0):
        Y = pin.computeJointTorqueRegressor(model, data, q, v, a)
        tau = params.columns(Y, v, a) @ params.nominal + params.known(Y, v, a)
        expected = (pin.rnea(model, data, q, v, a) + model.damping * v
                    + fc * np.tanh(v / COULOMB_SMOOTHING_RAD_S))
        worst = max(worst, float(np.abs(tau - expected).max() / max(1.0, np.abs(expected).max())))
    assert worst < tol


def test_regressor_times_parameters_is_rnea_two_link(two_link_torque_gravity):
    _check_regressor(two_link_torque_gravity)


def test_regressor_times_parameters_is_rnea_six_dof(six_dof):
    assert six_dof.nv == 6 and len(ParameterSet(six_dof).bodies) == 6  # the tool is welded: known
    _check_regressor(six_dof)


def test_regressor_times_parameters_is_rnea_g1(g1):
    _check_regressor(g1)


def test_subset_of_bodies_keeps_the_rest_as_known_torque(six_dof):
    full, sub = ParameterSet(six_dof), ParameterSet(six_dof, ["fore", "tool"])
    assert [b.name for b in sub.bodies] == ["fore", "tool"] and sub.n == 20
    model, data = six_dof.pin_model, six_dof.pin_model.createData()
    for q, v, a in _states(six_dof, 5, 1):
        Y = pin.computeJointTorqueRegressor(model, data, q, v, a)
        np.testing.assert_allclose(sub.columns(Y, v, a) @ sub.nominal + sub.known(Y, v, a),
                                   full.columns(Y, v, a) @ full.nominal + full.known(Y, v, a), atol=1e-11)


def test_projection_removes_any_contact_wrench(g1):
    """P J_c^T f = 0: the projected equations hold whatever the feet push."""
    params = ParameterSet(g1, ["torso_link"])
    model, data = g1.pin_model, g1.pin_model.createData()
    feet = ("left_ankle_roll_link", "right_ankle_roll_link")
    states = list(_states(g1, 4, 2))
    q, v, a = (np.array(x) for x in zip(*states, strict=True))
    rng = np.random.default_rng(3)
    tau = np.zeros((4, g1.nv))
    contacts = np.array([[True, True], [True, False], [False, True], [True, True]])
    wrenches = rng.standard_normal((4, 2, 6)) * 100 * contacts[:, :, None]
    for k in range(4):  # torques of the nominal robot under these contact wrenches
        pin.computeJointJacobians(model, data, q[k])
        f = sum(pin.getFrameJacobian(model, data, model.getFrameId(b, pin.FrameType.BODY),
                                     pin.LOCAL_WORLD_ALIGNED).T @ wrenches[k, i] for i, b in enumerate(feet))
        tau[k] = pin.rnea(model, data, q[k], v[k], a[k]) + model.damping * v[k] - f
        tau[k] += np.asarray(model.upperDryFrictionLimit) * np.tanh(v[k] / COULOMB_SMOOTHING_RAD_S)
    samples = Samples(np.arange(4.0), q, v, a, tau, contacts, feet, wrenches)
    for (W, y, P), on in zip(SampleEquations(params, samples, "projected"), contacts, strict=True):
        assert P.shape == (g1.nv - 6 * on.sum(), g1.nv)
        np.testing.assert_allclose(P @ (W @ params.nominal), P @ y, atol=1e-9)
    measured = stack(params, samples, "measured")
    assert measured.residual_sq(params.nominal) < 1e-16 * measured.y_sq
