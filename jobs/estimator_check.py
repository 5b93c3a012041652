"""The base-state estimator checked against the plant: the G1 standing, then squatting, in-process.

The whole-body controller holds the G1 (crouched start, CoM moved over the soles' centres in
1 s) and then squats, CoM 8 cm down at 0.5 Hz; each cycle the leg-kinematics estimator reads the
encoders and the IMU (:mod:`mbctl.sim.imu`, with optional noise) and its base pose is compared with
the plant's. Used by the tests (a few seconds) and bench/bench_dds.py (30 and 60 s).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from mbctl.jobs.g1_wbc import g1_whole_body
from mbctl.jobs.plant import g1_estimator
from mbctl.jobs.wbc_scenarios import SQUAT_AMPLITUDE_M, SQUAT_FREQUENCY_HZ
from mbctl.planners.polynomial import minimum_jerk_at
from mbctl.robots.g1 import crouched_start
from mbctl.robots.model_pair import Robot
from mbctl.robots.g1 import G1_IMU
from mbctl.sim.imu import ImuReader
from mbctl.sim.simulator import Simulator

STAND_S = 1.0


@dataclass(frozen=True)
class EstimatorCheck:
    """How far the estimate was from the plant.

    Attributes:
        position_error_max_m: Largest |p_est - p_true| [m] of the base.
        position_error_final_m: The same at the end [m].
        orientation_error_max_deg: Largest angle between the estimated and true base rotation [deg].
        base_z_range_m: How far the base moved up and down [m] (the squat's depth).
        foot_slip_m: How far the left foot slid on the floor in the plant [m] (unobservable).
        update_median_us: The estimator's update, median [us].
    """

    position_error_max_m: float
    position_error_final_m: float
    orientation_error_max_deg: float
    base_z_range_m: float
    foot_slip_m: float
    update_median_us: float


def squat_check(robot: Robot, seconds: float, imu_noise: float = 0.0, seed: int = 3) -> EstimatorCheck:
    """Stand ``STAND_S`` then squat until ``seconds``; the estimator's errors against the plant.

    Args:
        robot: The G1 in torque mode with palm sites (as g1-wbc loads it).
        seconds: Simulated time [s].
        imu_noise: IMU noise, a multiple of the model's declared sensor noise.
        seed: Seed of the noise.
    """
    sim = Simulator(robot)
    sim.reset("stand")
    sim.set_state(crouched_start(robot), np.zeros(robot.nv))
    wb = g1_whole_body(robot)
    wb.hold(sim.read_state())
    c0 = wb.com.target
    sim.forward()
    feet = [sim.site_pose(f)[0] for f in ("left_foot", "right_foot")]
    home = np.array([*(0.5 * (feet[0] + feet[1]))[:2], c0[2]])
    home[0] += float(np.mean([p[0] for p in wb.controller.contacts["left_foot"].contact.points_F]))
    reader = ImuReader(sim, G1_IMU, noise_scale=imu_noise, seed=seed)
    q0 = sim.read_state().q
    estimator = g1_estimator(robot, (float(q0[0]), float(q0[1])))
    estimator.reset(reader.proprioception())
    w, amplitude = 2 * np.pi * SQUAT_FREQUENCY_HZ, SQUAT_AMPLITUDE_M
    errors, angles, z, update_s = [], [], [], []
    for _ in range(int(round(seconds / sim.control_period_s))):
        t = max(0.0, sim.time_s - STAND_S)
        p, v, a = minimum_jerk_at(c0, home, sim.time_s, 0.0, STAND_S)
        wb.com.set_target(p - [0, 0, amplitude * (1 - np.cos(w * t))],
                          v - [0, 0, amplitude * w * np.sin(w * t)],
                          a - [0, 0, amplitude * w * w * np.cos(w * t)])
        sim.step(wb.controller.compute(sim.read_state()))
        t0 = time.perf_counter()
        q_base, _ = estimator.update(reader.proprioception())
        update_s.append(time.perf_counter() - t0)
        truth = sim.read_state()
        errors.append(float(np.linalg.norm(q_base[:3] - truth.q[:3])))
        R_err = pin.Quaternion(q_base[3:7]).matrix().T @ pin.Quaternion(truth.q[3:7]).matrix()
        angles.append(float(np.degrees(np.linalg.norm(pin.log3(R_err)))))
        z.append(float(truth.q[2]))
    slip = float(np.linalg.norm((sim.site_pose("left_foot")[0] - feet[0])[:2]))
    return EstimatorCheck(max(errors), errors[-1], max(angles), float(np.ptp(z)), slip,
                          float(np.median(update_s)) * 1e6)
