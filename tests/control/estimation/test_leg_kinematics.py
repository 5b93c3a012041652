"""The leg-kinematics estimator: setup errors, the reading gap, the protocol (the closed-loop squat
against the plant's truth is in tests/jobs/test_estimator_check.py; the 30 s runs in bench/)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from mbctl.control.estimation import EstimatorError, LegKinematicsEstimator, LegKinematicsNoise
from mbctl.control.wbc import foot_contact_from_model
from mbctl.robots.g1 import FEET, G1_IMU
from mbctl.robots.interface import BASE_POSITION
from mbctl.sim.imu import ImuReader
from mbctl.sim.simulator import Simulator


def g1_estimator(robot, ground_noise_m=None):
    """The estimator on the G1's feet (contact point: each sole's centre) and its pelvis IMU."""
    feet = {f: foot_contact_from_model(robot, f).points_F.mean(axis=0) for f in FEET}
    return LegKinematicsEstimator(robot, feet, G1_IMU.site, ground_noise_m=ground_noise_m)


def _started(robot, ground_noise_m=None):
    """The estimator reset on the first reading of the G1 standing in MuJoCo; (estimator, reading)."""
    sim = Simulator(robot)
    sim.reset("stand")
    first = ImuReader(sim, G1_IMU).proprioception()
    estimator = g1_estimator(robot, ground_noise_m)
    estimator.reset(first)
    return estimator, first


def test_it_estimates_the_base_position(g1_torque):
    estimator = g1_estimator(g1_torque)
    assert BASE_POSITION in estimator.estimated


def test_bad_setups_are_named(g1_torque, two_link):
    feet = {"left_foot": np.zeros(3)}
    with pytest.raises(EstimatorError, match="fixed base"):
        LegKinematicsEstimator(two_link, feet, "imu")
    with pytest.raises(EstimatorError, match=r"unknown frames \['left_fot'\]"):
        LegKinematicsEstimator(g1_torque, {"left_fot": np.zeros(3)}, G1_IMU.site)
    with pytest.raises(EstimatorError, match="at least one foot"):
        LegKinematicsEstimator(g1_torque, {}, G1_IMU.site)
    with pytest.raises(EstimatorError, match="noise kinematics_m must be finite and > 0"):
        LegKinematicsNoise(kinematics_m=0.0)
    with pytest.raises(EstimatorError, match="ground_noise_m must be finite and > 0"):
        LegKinematicsEstimator(g1_torque, feet, G1_IMU.site, ground_noise_m=0.0)
    estimator = LegKinematicsEstimator(g1_torque, feet, G1_IMU.site)
    sim = Simulator(g1_torque)
    sim.reset("stand")
    with pytest.raises(EstimatorError, match="call reset"):
        estimator.update(ImuReader(sim, G1_IMU).proprioception())
    with pytest.raises(EstimatorError, match="unknown foot 'right_foot'"):
        estimator.set_contacts({"right_foot": False})


def test_a_gap_in_the_readings_does_not_throw_the_estimate(g1_torque):
    # a process that stalls 1 s between two readings (the DDS client before its loop starts) must
    # not integrate the accelerometer over the whole gap
    estimator, first = _started(g1_torque)
    shaken = first.imu._replace(accel_I=first.imu.accel_I + [3.0, 0.0, 0.0])
    q_base, _ = estimator.update(first._replace(time_s=first.time_s + 1.0, imu=shaken))
    assert abs(q_base[0]) < 5e-3


@pytest.mark.parametrize("ground_noise_m", [None, 0.002])
def test_the_per_axis_filter_is_the_full_kalman_filter(g1_torque, ground_noise_m):
    # the estimator keeps one (2 + n) covariance for the three world axes (with the flat-ground
    # measurement, one for x and y and one for z); the textbook filter on the whole (6 + 3 n) state,
    # written out here, must give the same state and covariance every step, through noisy IMU
    # readings, a moving leg and a foot leaving and regaining contact
    est, first = _started(g1_torque, ground_noise_m)
    n, nz = len(est.feet), est.noise
    x, P = est.x, np.diag([1e-6] * 3 + [1e-4] * 3 + [1e-6] * 3 * n)
    np.testing.assert_array_equal(est.P, P)
    rng = np.random.default_rng(7)
    I3, t = np.eye(3), first.time_s
    for k in range(60):
        contact = np.array([True, k < 20 or k >= 40])  # the right foot lifted for steps 20-39
        est.set_contacts(dict(zip(est.feet, contact.tolist(), strict=True)))
        t += 0.002
        nj = len(first.q_joints)
        r = first._replace(time_s=t, q_joints=first.q_joints + 0.02 * rng.standard_normal(nj),
                           v_joints=0.3 * rng.standard_normal(nj),
                           imu=first.imu._replace(accel_I=first.imu.accel_I + rng.standard_normal(3),
                                                  gyro_I=0.1 * rng.standard_normal(3)))
        q_base, _ = est.update(r)
        # the full filter: predict ...
        w, qx, qy, qz = r.imu.quat_wxyz  # (R_WI from Pinocchio, R_WB = R_WI R_BI^T: not the estimator's)
        R_WI = pin.Quaternion(float(w), float(qx), float(qy), float(qz)).normalized().toRotationMatrix()
        R_WB = R_WI @ est._R_BI.T
        np.testing.assert_allclose(est._orientation(r)[0], R_WB, rtol=0, atol=1e-14)
        x_q, y_q, z_q, w_q = q_base[3:].tolist()  # the base's quaternion (x, y, z, w) is R_WB's
        np.testing.assert_allclose(pin.Quaternion(w_q, x_q, y_q, z_q).toRotationMatrix(), R_WB, atol=1e-12)
        a_W = R_WI @ r.imu.accel_I + est._g_W
        F = np.eye(6 + 3 * n)
        F[:3, 3:6] = 0.002 * I3
        x = F @ x
        x[:3] += 0.5 * 0.002**2 * a_W
        x[3:6] += a_W * 0.002
        walk = np.repeat(np.where(contact, nz.foot_slip_m_s, nz.foot_swing_m_s) ** 2, 3) * 0.002
        Q = np.diag(np.concatenate([np.full(3, (0.5 * nz.accel_m_s2 * 0.002**2) ** 2),
                                    np.full(3, nz.accel_m_s2**2 * 0.002), walk]))
        P = F @ P @ F.T + Q
        # ... and correct with each foot in contact (position relative to the base, base velocity)
        w_B = est._R_BI @ r.imu.gyro_I
        p_BP, v_B = est._legs(r, w_B.tolist())
        rows, z, noise = [], [], []
        for i in np.flatnonzero(contact):
            h = np.zeros((3, 6 + 3 * n))
            h[:, :3], h[:, 6 + 3 * i:9 + 3 * i] = -I3, I3
            rows.append(h), z.append(R_WB @ p_BP[i]), noise.append(np.full(3, nz.kinematics_m**2))
        for i in np.flatnonzero(contact):
            h = np.zeros((3, 6 + 3 * n))
            h[:, 3:6] = I3
            rows.append(h), z.append(R_WB @ v_B[i]), noise.append(np.full(3, nz.leg_velocity_m_s**2))
        for i in np.flatnonzero(contact) if ground_noise_m else ():  # on flat ground: the foot's z
            h = np.zeros((1, 6 + 3 * n))
            h[0, 6 + 3 * i + 2] = 1.0
            rows.append(h), z.append([est.ground_z_m]), noise.append([ground_noise_m**2])
        H, zv = np.vstack(rows), np.concatenate(z)
        R = np.diag(np.concatenate(noise))
        K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
        x = x + K @ (zv - H @ x)
        IKH = np.eye(len(x)) - K @ H
        P = IKH @ P @ IKH.T + K @ R @ K.T  # (Joseph's form: (I - K H) P lost digits on z's ground rows)
        np.testing.assert_allclose(est.x, x, rtol=0, atol=1e-9)
        np.testing.assert_allclose(est.P, 0.5 * (P + P.T), rtol=1e-6, atol=1e-15)


@pytest.mark.parametrize("ground_noise_m", [None, 0.002])
def test_on_flat_ground_a_height_carried_from_foot_to_foot_returns_to_the_ground(g1_torque, ground_noise_m):
    # a foot that lands takes its height from the base's: an error of the height (here 1 cm, base and
    # feet alike, as steps on a rolling sole leave it) stays without the flat-ground measurement
    # and is corrected with it
    est, first = _started(g1_torque, ground_noise_m)
    z0 = est.x[2]
    est._X[:, 2] += 0.01
    for k in range(1, 251):  # 0.5 s standing
        q_base, _ = est.update(first._replace(time_s=first.time_s + 0.002 * k))
    if ground_noise_m is None:
        assert q_base[2] - z0 == pytest.approx(0.01, abs=1e-3)
    else:
        assert abs(q_base[2] - z0) < 1e-3
