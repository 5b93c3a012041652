"""The WBC cycle's fast paths against their general forms: [M, -Jc^T]'s rows written in place
against picked by index, the torques from the fast path's G x against T x + b, the command and
the solution built without their generated constructors against those."""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest

from mbctl.robots.interface import RobotState
from tests.control.wbc.test_wbc import _moving_state, _stance


@pytest.mark.parametrize("released", ["l_sole", "r_sole"])
def test_the_rows_in_order_equal_the_rows_picked_by_index_through_a_release(tiny_biped, crouch, released):
    """[M, -Jc^T] written in place (the free flyer's dofs first) against its rows picked by index
    (the general path), on moving states while one foot's force ramps down and after it is
    released (its rows dropped: the other foot's and the base's moved up); the base's dynamics
    rows hold at the solution: M_u vdot + b_u = Jc_u^T f."""
    ctrls = []
    for general in (False, True):
        wb, _ = _stance(tiny_biped, crouch)
        if general:
            wb.controller._dyn_rows = np.arange(tiny_biped.nv)  # the private hook: M[rows], indexed
        ctrls.append(wb.controller)
    assert ctrls[0]._dyn_rows is None
    for k in range(400):
        if k == 50:
            for ctrl in ctrls:
                ctrl.release(released)
        state = _moving_state(tiny_biped, crouch, seed=k)
        state = RobotState(state.q, state.v, 0.002 * k)
        taus = [ctrl.compute(state).values for ctrl in ctrls]
        np.testing.assert_allclose(taus[0], taus[1], rtol=0.0, atol=1e-12)
        for ctrl in ctrls:
            sol, s = ctrl.solution, ctrl.state
            base = s.M[:6] @ sol.vdot + s.b[:6] + ctrl._JcT_neg[:6] @ sol.forces
            assert np.abs(base).max() < 1e-8, k
    assert ctrls[0].contact_released(released)
    np.testing.assert_array_equal(ctrls[0].solution.forces[ctrls[0].solution.force_slices[released]], 0.0)
    assert np.abs(taus[0]).max() > 1.0


def test_the_solution_is_a_frozen_dataclass_with_its_fields():
    """WBCSolution's hand-written __init__ keeps the dataclass: fields, frozen, replace, equality."""

    from mbctl.control.wbc.config import WBCSolution

    tau, vdot, forces = np.arange(3.0), np.arange(4.0), np.arange(6.0)
    X = pin.SE3.Random()
    args = (tau, vdot, forces, {"l": slice(0, 6)}, {"l": np.zeros((2, 3))}, (X.homogeneous,), np.eye(6),
            1e-4, 5e-5)
    sol = WBCSolution(*args)
    assert [getattr(sol, f.name) for f in dataclasses.fields(sol)][:9] == list(args) and not sol.fallback
    assert WBCSolution(*args, fallback=True).fallback
    assert sol.foot_poses_W["l"].isApprox(X, 1e-15)  # the poses as Pinocchio's, from the array
    with pytest.raises(dataclasses.FrozenInstanceError):
        sol.tau = tau  # type: ignore[misc]
    later = dataclasses.replace(sol, qp_time_s=7e-5)
    assert later.qp_time_s == 7e-5 and later.tau is tau and sol.qp_time_s == 5e-5
    np.testing.assert_array_equal(sol.forces_F["l"], forces.reshape(2, 3))


def test_the_torques_from_the_fast_paths_rows_equal_t_x_plus_b(tiny_biped, crouch, monkeypatch):
    """tau from the fast path's G x (its torque rows) against T x + b_a, and on the other paths."""
    wb, _ = _stance(tiny_biped, crouch)
    ctrl = wb.controller
    v = 0.02 * np.random.default_rng(9).normal(size=tiny_biped.nv)  # moving, no inequality active
    state = RobotState(crouch(tiny_biped), v, 0.0)

    def general(ctrl):
        x = np.concatenate([ctrl.solution.vdot, ctrl.solution.forces])
        return ctrl._T @ x + ctrl.state.b[ctrl._a]

    ctrl.compute(state)
    assert ctrl.fast_path_cycles == 1 and ctrl._qp.Gx is not None
    np.testing.assert_allclose(ctrl.solution.tau, general(ctrl), rtol=0.0, atol=1e-12)
    fast = ctrl.solution.tau
    monkeypatch.setattr(ctrl._qp, "_kkt", lambda m_eq: (None, np.arange(m_eq)))  # no fast path
    ctrl.compute(state)  # the QP in the forces alone (control/wbc/force_space.py): its check's G x
    assert ctrl.daqp_cycles == 1 and ctrl._qp.Gx is not None
    np.testing.assert_allclose(ctrl.solution.tau, general(ctrl), rtol=0.0, atol=1e-12)
    np.testing.assert_allclose(ctrl.solution.tau, fast, rtol=0.0, atol=1e-5)  # (daqp tolerance)
    ctrl.config = dataclasses.replace(ctrl.config, force_space=False)  # daqp on the QP in vdot and forces
    ctrl.compute(state)
    assert ctrl.daqp_cycles == 2 and ctrl._qp.Gx is None
    np.testing.assert_allclose(ctrl.solution.tau, general(ctrl), rtol=0.0, atol=1e-12)
    np.testing.assert_allclose(ctrl.solution.tau, fast, rtol=0.0, atol=1e-5)  # (daqp tolerance)
    assert np.abs(ctrl.solution.tau).max() > 1.0

