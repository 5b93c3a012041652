"""The leg-kinematics estimator: setup errors, the reading gap, the protocol (the closed-loop squat
against the plant's truth is in tests/jobs/test_estimator_check.py; the 30 s runs in bench/)."""

from __future__ import annotations

import numpy as np
import pytest

from mbctl.control.estimation import EstimatorError, LegKinematicsEstimator, LegKinematicsNoise
from mbctl.control.wbc import foot_contact_from_model
from mbctl.robots.g1 import FEET, G1_IMU
from mbctl.robots.interface import BASE_POSITION
from mbctl.sim.imu import ImuReader
from mbctl.sim.simulator import Simulator


def g1_estimator(robot):
    """The estimator on the G1's feet (contact point: each sole's centre) and its pelvis IMU."""
    feet = {f: foot_contact_from_model(robot, f).points_F.mean(axis=0) for f in FEET}
    return LegKinematicsEstimator(robot, feet, G1_IMU.site)


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
    sim = Simulator(g1_torque)
    sim.reset("stand")
    reader = ImuReader(sim, G1_IMU)
    estimator = g1_estimator(g1_torque)
    first = reader.proprioception()
    estimator.reset(first)
    shaken = first.imu._replace(accel_I=first.imu.accel_I + [3.0, 0.0, 0.0])
    q_base, _ = estimator.update(first._replace(time_s=first.time_s + 1.0, imu=shaken))
    assert abs(q_base[0]) < 5e-3
