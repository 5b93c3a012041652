"""The leg-kinematics estimator against the plant's truth (the 30 s runs are in bench/bench_dds.py)."""

from __future__ import annotations

import numpy as np
import pytest

from mbctl.control.estimation import EstimatorError, LegKinematicsEstimator, LegKinematicsNoise
from mbctl.jobs.estimator_check import squat_check
from mbctl.jobs.plant import g1_estimator
from mbctl.jobs.robot_constants import with_palm_sites
from mbctl.robots.edits import position_to_motor
from mbctl.robots.interface import BASE_POSITION, BaseStateEstimator
from mbctl.robots.unitree import G1_IMU
from mbctl.sim.imu import ImuReader
from mbctl.sim.simulator import Simulator


@pytest.fixture(scope="module")
def g1_torque(g1):
    return position_to_motor(with_palm_sites(g1))


def test_estimate_follows_the_plant_through_a_squat(g1_torque):
    check = squat_check(g1_torque, 2.0)  # 1 s standing, then down to the bottom of the squat
    assert check.base_z_range_m > 0.1  # it did squat (the base moves ~0.2 m)
    assert check.position_error_max_m < 5e-3 and check.orientation_error_max_deg < 0.5


def test_estimate_with_the_models_imu_noise(g1_torque):
    check = squat_check(g1_torque, 1.5, imu_noise=1.0)
    assert check.position_error_max_m < 5e-3 and check.orientation_error_max_deg < 0.5


def test_it_is_a_base_state_estimator(g1_torque):
    estimator = g1_estimator(g1_torque)
    assert isinstance(estimator, BaseStateEstimator)
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
