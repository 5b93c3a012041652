"""The leg-kinematics estimator against the plant's truth (the 30 s runs are in bench/bench_dds.py)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from mbctl.control.estimation import EstimatorError, LegKinematicsEstimator, LegKinematicsNoise
from mbctl.jobs.g1_wbc import crouched_start, g1_whole_body
from mbctl.jobs.plant import g1_estimator
from mbctl.jobs.robot_constants import with_palm_sites
from mbctl.robots.edits import position_to_motor
from mbctl.robots.interface import BASE_POSITION, BaseStateEstimator
from mbctl.robots.unitree import G1_IMU
from mbctl.sim.imu import ImuReader
from mbctl.sim.simulator import Simulator


def squat(robot, seconds: float, imu_noise: float = 0.0):
    """The whole-body controller standing (1 s) then squatting (CoM 8 cm at 0.5 Hz) on the plant.

    Returns the largest base position error [m] and orientation error [deg] of the estimate, and
    the base's height range [m] (so the test knows it squatted).
    """
    sim = Simulator(robot)
    sim.reset("stand")
    sim.set_state(crouched_start(robot), np.zeros(robot.nv))
    wb = g1_whole_body(robot)
    wb.hold(sim.read_state())
    c0 = wb.com.p_ref.copy()
    reader = ImuReader(sim, G1_IMU, noise_scale=imu_noise, seed=3)
    q0 = sim.read_state().q
    estimator = g1_estimator(robot, (float(q0[0]), float(q0[1])))
    estimator.reset(reader.proprioception())
    w, amplitude = np.pi, 0.08
    pos_err, ang_err, z = 0.0, 0.0, []
    for _ in range(int(seconds / sim.control_period_s)):
        t = max(0.0, sim.time_s - 1.0)
        wb.com.set_reference(c0 - [0, 0, amplitude * (1 - np.cos(w * t))],
                             -np.array([0, 0, amplitude * w * np.sin(w * t)]),
                             -np.array([0, 0, amplitude * w * w * np.cos(w * t)]))
        sim.step(wb.controller.compute(sim.read_state(), dt_s=sim.control_period_s))
        q_base, v_base = estimator.update(reader.proprioception())
        truth = sim.read_state()
        pos_err = max(pos_err, float(np.linalg.norm(q_base[:3] - truth.q[:3])))
        R_err = pin.Quaternion(q_base[3:7]).matrix().T @ pin.Quaternion(truth.q[3:7]).matrix()
        ang_err = max(ang_err, float(np.degrees(np.linalg.norm(pin.log3(R_err)))))
        z.append(truth.q[2])
    return pos_err, ang_err, np.ptp(z)


@pytest.fixture(scope="module")
def g1_torque(g1):
    return position_to_motor(with_palm_sites(g1))


def test_estimate_follows_the_plant_through_a_squat(g1_torque):
    pos_err, ang_err, dz = squat(g1_torque, 3.0)
    assert dz > 0.1  # it did squat (the base moves ~0.2 m)
    assert pos_err < 5e-3 and ang_err < 0.5


def test_estimate_with_the_models_imu_noise(g1_torque):
    pos_err, ang_err, _ = squat(g1_torque, 2.0, imu_noise=1.0)
    assert pos_err < 5e-3 and ang_err < 0.5


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
