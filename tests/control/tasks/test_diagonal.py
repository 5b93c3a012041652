"""DiagonalTask, the base of posture and damping: ``J = diag(mask)`` (the free flyer's dofs masked
wherever it sits), ``cost^2 mask`` cached per cost, and the stack's diagonal shortcut giving the
same H and c as the task's dense rows (the masked-out entries of its errors may hold anything)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from mbctl.control.tasks import AccelerationGains, DynamicsState, KinematicState, TaskStack
from mbctl.control.tasks.base import floating_dofs
from mbctl.control.tasks.diagonal import DiagonalTask
from mbctl.control.tasks.residuals import TaskResidual
from tests.control.tasks.conftest import ARM, FLOATING, FLOATING_HINGES, joint_mask, random_q


class _Constant(DiagonalTask):
    """``e`` and ``a_des`` given, with junk where the mask is 0 in the masked variants (allowed)."""

    def __init__(self, model: pin.Model, cost, gain: float, e: np.ndarray, a_des: np.ndarray,
                 lm_damping: float = 0.0):
        super().__init__("constant", model, cost, gain, lm_damping, AccelerationGains())
        self.e, self.a_des = e, a_des

    def compute_error(self, state):
        return self.e * self.mask

    def masked_error(self, state):
        return self.e

    def compute_jacobian(self, state):
        return self._jacobian

    def jacobian_and_drift(self, state):
        return self._jacobian, np.zeros(self.k)

    def desired_acceleration(self, state, J):
        return self.a_des * self.mask

    def masked_desired_acceleration(self, state):
        return self.a_des

    def residual(self, state):
        return TaskResidual(deviation=0.0)


def test_the_mask_drops_the_free_flyer_wherever_it_sits():
    # a free flyer below a hinge (a robot on a turntable): dofs 1..6 masked, the hinge's kept
    model = pin.Model()
    turntable = model.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "turntable")
    model.appendBodyToJoint(turntable, pin.Inertia.FromBox(1.0, 0.1, 0.1, 0.1), pin.SE3.Identity())
    body = model.addJoint(turntable, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "body")
    model.appendBodyToJoint(body, pin.Inertia.FromBox(1.0, 0.1, 0.1, 0.1), pin.SE3.Identity())
    assert floating_dofs(model).tolist() == [1, 2, 3, 4, 5, 6]
    task = _Constant(model, 1.0, 1.0, np.zeros(7), np.zeros(7))
    np.testing.assert_array_equal(task.mask, [1, 0, 0, 0, 0, 0, 0])
    np.testing.assert_array_equal(task.compute_jacobian(None), np.diag(task.mask))
    for model in (ARM, FLOATING):
        np.testing.assert_array_equal(_Constant(model, 1.0, 1.0, 0, 0).mask, joint_mask(model))
    with pytest.raises(ValueError, match="read-only"):
        task.mask[0] = 0.0


def test_cost_squared_mask_follows_set_cost():
    task = _Constant(FLOATING_HINGES, 2.0, 1.0, 0, 0)
    np.testing.assert_array_equal(task.cost2_mask(), 4.0 * joint_mask(FLOATING_HINGES))
    assert task.cost2_mask() is task.cost2_mask()  # cached
    cost = np.arange(FLOATING_HINGES.nv, dtype=float)
    task.set_cost(cost)
    np.testing.assert_array_equal(task.cost2_mask(), cost**2 * joint_mask(FLOATING_HINGES))


@pytest.mark.parametrize("model", [ARM, FLOATING, FLOATING_HINGES], ids=lambda m: m.name)
def test_the_diagonal_shortcut_equals_the_dense_rows(model):
    rng = np.random.default_rng(13)
    q, v = random_q(model, rng), rng.standard_normal(model.nv)
    cost = rng.uniform(0.5, 2.0, model.nv)
    e, a_des = rng.standard_normal(model.nv), rng.standard_normal(model.nv)
    shortcut = _Constant(model, cost, 0.7, e, a_des, lm_damping=0.3)
    dense = _Constant(model, cost, 0.7, e, a_des, lm_damping=0.3)
    dense.is_diagonal = False  # the stack then asks it for its nv rows
    kin, dyn = KinematicState(model, q), DynamicsState(model, q, v)
    objectives = []
    for task in (shortcut, dense):
        stack = TaskStack(model.nv, [task])
        H_v, c_v = np.full((model.nv, model.nv), np.nan), np.full(model.nv, np.nan)
        mu = stack.velocity_objective(kin, H_v, c_v)
        H_a, c_a = np.full((model.nv, model.nv), np.nan), np.full(model.nv, np.nan)
        stack.acceleration_objective(dyn, H_a, c_a)
        objectives.append((H_v, c_v, H_a, c_a, np.array(mu)))
    for a, b in zip(*objectives, strict=True):
        np.testing.assert_allclose(a, b, atol=1e-14)
    # and both what the rows give: H = diag(cost^2 mask); c = gain cost^2 mask e, -cost^2 mask a_des;
    # mu = lm |gain cost mask e|^2
    mask = joint_mask(model)
    H_v, c_v, H_a, c_a, mu = objectives[0]
    assert float(mu) == pytest.approx(0.3 * float(np.sum((0.7 * cost * mask * e) ** 2)), rel=1e-13)
    np.testing.assert_allclose(H_v, np.diag(cost**2 * mask), atol=1e-15)
    np.testing.assert_allclose(c_v, 0.7 * cost**2 * mask * e, atol=1e-15)
    np.testing.assert_allclose(H_a, np.diag(cost**2 * mask), atol=1e-15)
    np.testing.assert_allclose(c_a, -(cost**2) * mask * a_des, atol=1e-15)
