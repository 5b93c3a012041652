"""The estimate: kept at the prior where the data are silent, physical always, friction non-negative."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from mbctl.robots.edits import scale_link_masses
from mbctl.robots.identification import IdentifyOptions, RecordedLog, identify
from mbctl.robots.identification.estimate import estimate
from mbctl.robots.identification.identifiability import analyse, reasons
from mbctl.robots.identification.inertial import consistency_problems
from mbctl.robots.identification.parameters import ParameterSet
from mbctl.robots.identification.regressor import LinearSystem, stack
from mbctl.robots.identification.samples import Samples
from mbctl.robots.registry import load_robot


def _log(robot, plant, q_of_t, duration=4.0):
    """Inverse dynamics of the plant along q(t): an exact log (no simulation needed).

    Every sample satisfies the plant's equation of motion exactly, with the acceleration the
    forward difference of the logged v (as in a semi-implicit Euler step).
    """
    dt = robot.timestep_s
    t = np.arange(int(duration / dt)) * dt
    q, v, a = q_of_t(t)
    model, data = plant.pin_model, plant.pin_model.createData()
    # v sampled so that forward differences give a exactly (a semi-implicit Euler plant)
    v_log = np.vstack([v[:1], v[:1] + np.cumsum(a[:-1] * dt, axis=0)])
    tau = np.array([pin.rnea(model, data, q[k], v_log[k], a[k]) for k in range(len(t))])
    return RecordedLog(t, q, v_log, tau, tuple(robot.joints))


def test_parameters_the_data_never_see_keep_their_nominal_values():
    """The shoulder never moves and gravity is off: link1's parameters enter no torque at all."""
    nominal = load_robot("two_link_torque")
    plant = scale_link_masses(nominal, 1.2)

    def q_of_t(t):
        w, amp = 2 * np.pi * np.array([0.7, 1.3]), np.array([0.5, 0.3])
        s, c = np.sin(np.outer(t, w)), np.cos(np.outer(t, w))
        zero = np.zeros_like(t)
        return (np.stack([zero, s @ amp], axis=1), np.stack([zero, c @ (amp * w)], axis=1),
                np.stack([zero, -s @ (amp * w**2)], axis=1))

    ident = identify(nominal, [_log(nominal, plant, q_of_t)],
                     IdentifyOptions(cutoff_hz=None, rate_hz=None, structural_samples=0))
    link1 = ident.params.body("link1")
    np.testing.assert_allclose(ident.theta[link1.columns], link1.nominal, rtol=1e-9, atol=1e-12)
    why = reasons(ident.data, None)
    assert all(why[f"link1.{p}"].startswith("no torque in this log depends on it") for p in ("m", "Izz"))
    np.testing.assert_allclose(ident.estimate.std[link1.columns], ident.params.prior_std()[link1.columns],
                               rtol=1e-6)


def test_the_estimate_is_physical_when_the_data_ask_for_an_unphysical_body():
    robot = load_robot("two_link_torque", gravity=True)
    params = ParameterSet(robot, friction=True)
    n = params.n
    # one overwhelming equation: link2's rotational inertia about z is -1 kg m^2, and a friction < 0
    W = np.zeros((2, n))
    W[0, params.names.index("link2.Izz")] = 1e3
    W[1, params.names.index("elbow.fc")] = 1e3
    y = np.array([-1e3, -1e3])
    R = np.linalg.qr(W, mode="r")
    R = np.vstack([R, np.zeros((n - R.shape[0], n))])
    z = np.concatenate([np.linalg.qr(W)[0].T @ y, np.zeros(n - 2)])
    system = LinearSystem(R, z, 0.0, 2, float(y @ y))
    result = estimate(params, system, rank=2)
    assert result.constrained and result.iterations > 0
    for b in params.bodies:
        assert consistency_problems(result.theta[b.columns]) == [], b.name
    assert result.theta[params.names.index("elbow.fc")] >= 0.0


def test_identifiability_names_rank_and_structural_base_parameters(two_link_torque_gravity):
    params = ParameterSet(two_link_torque_gravity)
    rng = np.random.default_rng(0)
    n_s = 50
    q = rng.uniform(-3, 3, (n_s, 2))
    v, a = rng.standard_normal((2, n_s, 2))
    no_contacts = np.zeros((n_s, 0), dtype=bool)
    samples = Samples(np.arange(n_s, dtype=float), q, v, a, np.zeros((n_s, 2)), no_contacts, ())
    result = analyse(stack(params, samples), params.names, params.prior_std())
    assert result.rank == len(result.base) == 6  # the planar 2R arm in gravity: 6 base parameters
    assert result.condition_number < 1e4
    assert [params.names[i] for i in np.flatnonzero(result.identifiable)] == ["link1.mcy"]


@pytest.mark.parametrize("bodies, message", [(["nope"], "Unknown identified body|Unknown robot body"),
                                             (["ee_body", "nope"], "nope")])
def test_unknown_bodies_are_named(two_link_torque_gravity, bodies, message):
    from mbctl.robots.exceptions import UnknownNameError

    with pytest.raises(UnknownNameError, match=message):
        ParameterSet(two_link_torque_gravity, bodies)
