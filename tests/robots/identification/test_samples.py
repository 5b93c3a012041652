"""From a log to samples: the checks, forward differences, exclusions, noise, write-back."""

from __future__ import annotations

import numpy as np
import pytest

from mbctl.robots.identification import BadLogError, InconsistentParameters, RecordedLog, add_noise
from mbctl.robots.identification.parameters import ParameterSet
from mbctl.robots.identification.samples import prepare_samples, split
from mbctl.robots.identification.writeback import identified_spec, identified_xml
from mbctl.robots.registry import load_robot


def _log(n=2000, dt=0.002, **extra):
    t = np.arange(n) * dt
    a = np.stack([np.cos(t), np.sin(2 * t)], axis=1)
    v = np.vstack([np.zeros((1, 2)), np.cumsum(a[:-1] * dt, axis=0)])
    q = np.cumsum(v * dt, axis=0)
    return RecordedLog(t, q, v, np.ones((n, 2)), ("shoulder", "elbow"), **extra)


def test_forward_differences_recover_the_acceleration_exactly(two_link_torque):
    log = _log()
    samples = prepare_samples(two_link_torque, log, cutoff_hz=None, rate_hz=None)
    expected = np.stack([np.cos(samples.t_s), np.sin(2 * samples.t_s)], axis=1)
    np.testing.assert_allclose(samples.a, expected, atol=1e-12)
    filtered = prepare_samples(two_link_torque, log, cutoff_hz=10.0, rate_hz=100.0)
    assert len(filtered) < len(samples) / 4  # decimated
    np.testing.assert_allclose(filtered.a, np.stack([np.cos(filtered.t_s), np.sin(2 * filtered.t_s)], axis=1),
                               atol=1e-3)


def test_samples_near_contact_changes_and_other_contacts_are_excluded(two_link_torque):
    n = 2000
    contacts = np.ones((n, 1), dtype=bool)
    contacts[1000:] = False
    others = np.zeros(n, dtype=int)
    others[1500] = 2
    log = _log(n, contact_bodies=("link2",), contacts=contacts, other_contacts=others)
    samples = prepare_samples(two_link_torque, log, cutoff_hz=None, rate_hz=None, margin_s=0.1)
    assert samples.excluded == {"filter transients at the ends": 2, "contact changes (impacts)": 101,
                                "other contacts on the robot": 101}
    assert not np.any((samples.t_s > 1.9) & (samples.t_s < 2.1))
    train, val = split(samples, 0.25)
    assert train.t_s.max() < val.t_s.min()


def test_bad_logs_name_what_is_wrong(two_link_torque):
    with pytest.raises(BadLogError, match="too short: 20 rows"):
        prepare_samples(two_link_torque, _log(20))
    log = _log()
    log.tau[7, 1] = np.inf
    with pytest.raises(BadLogError, match="non-finite values in tau, the first at data row 7, tau column 1"):
        prepare_samples(two_link_torque, log)
    with pytest.raises(BadLogError, match="joints \\['hip'\\] that 'two_link_torque' does not have"):
        prepare_samples(two_link_torque, RecordedLog(log.t_s, log.q, log.v, log.tau[:, :1], ("hip",)))
    with pytest.raises(BadLogError, match="Nyquist"):
        prepare_samples(two_link_torque, _log(), cutoff_hz=400.0)


def test_noise_has_the_asked_size(two_link_torque):
    log = _log(20000)
    noisy = add_noise(two_link_torque, log, torque_pct=1.0, encoder_rad=1e-4, seed=1)
    assert np.std(noisy.tau - log.tau) == pytest.approx(0.01, rel=0.05)
    assert np.std(noisy.q - log.q) == pytest.approx(1e-4, rel=0.05)
    assert np.std(noisy.v - log.v) == pytest.approx(np.sqrt(2) * 1e-4 / 0.002, rel=0.05)


def test_write_back_carries_inertials_friction_and_armature(two_link_torque, tmp_path):
    params = ParameterSet(two_link_torque, friction=True, armature=True)
    theta = params.nominal.copy() * 1.1  # a uniformly heavier arm stays physical
    theta[[params.names.index(n) for n in ("elbow.fv", "elbow.fc", "elbow.Ia")]] = [0.05, 0.2, 0.003]
    path = tmp_path / "identified.xml"
    path.write_text(identified_xml(two_link_torque, params, theta))
    again = ParameterSet(load_robot(path), friction=True, armature=True)
    np.testing.assert_allclose(again.nominal, theta, rtol=1e-5, atol=1e-9)  # MuJoCo writes 6 digits
    bad = params.nominal.copy()
    bad[params.body("link2").columns.start] = -0.7
    with pytest.raises(InconsistentParameters, match="body 'link2': mass -0.7 kg is not > 0; not written"):
        identified_spec(two_link_torque, params, bad)


def test_a_body_on_the_triangle_boundary_is_written_so_mujoco_compiles_it(two_link_torque, tmp_path):
    """A thin rod (moments ~0, b, b + 4e-13): MuJoCo's 6 digits must not round it to the wrong side."""
    from mbctl.robots.identification.inertial import from_inertial

    params = ParameterSet(two_link_torque)
    theta = params.nominal.copy()
    R = np.linalg.qr(np.random.default_rng(0).standard_normal((3, 3)))[0]
    rod = R @ np.diag([3.1e-13, 7.766444e-05, 7.7664440300e-05]) @ R.T
    theta[params.body("link2").columns] = from_inertial(0.33, np.array([0.09, -0.01, 0.0]), rod)
    path = tmp_path / "rod.xml"
    path.write_text(identified_xml(two_link_torque, params, theta))
    robot = load_robot(path)  # MuJoCo checks A + B >= C when it compiles
    assert robot.mj_model.body_mass[robot.body_id("link2")] == pytest.approx(0.33)
