"""The base-state estimator checked against the plant: the G1 standing, then squatting, in-process.

The whole-body controller holds the G1 (crouched start, CoM moved over the soles' centres in
1 s) and then squats, CoM 8 cm down at 0.5 Hz; each cycle the leg-kinematics estimator reads the
encoders and the IMU (:mod:`mbctl.sim.imu`, with optional noise) and its base pose is compared with
the plant's. It runs in the control loop every plant uses (:func:`mbctl.control.loop.run`). Used by the
tests (a few seconds) and bench/bench_dds.py (30 and 60 s).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from mbctl.control.estimation import LegKinematicsEstimator
from mbctl.control.loop import run
from mbctl.control.wbc import Scheduled
from mbctl.jobs.g1_wbc import g1_whole_body
from mbctl.jobs.plant import g1_estimator
from mbctl.jobs.wbc_scenarios import SQUAT_AMPLITUDE_M, SQUAT_FREQUENCY_HZ
from mbctl.planners.polynomial import minimum_jerk_at
from mbctl.robots.commands import Command
from mbctl.robots.g1 import FEET, G1_IMU, KEYFRAME, crouched_start
from mbctl.robots.interface import RobotState
from mbctl.robots.model_pair import Robot
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

    The whole-body controller runs in the control loop every plant uses (:func:`mbctl.control.loop.run`,
    the controller :class:`~mbctl.control.wbc.Scheduled`); after each cycle the estimator reads the
    encoders and the IMU and its base pose is compared with the plant's (:class:`_Comparison`).

    Args:
        robot: The G1 in torque mode with palm sites (as g1-wbc loads it).
        seconds: Simulated time [s].
        imu_noise: IMU noise, a multiple of the model's declared sensor noise.
        seed: Seed of the noise.
    """
    sim = Simulator(robot)
    sim.reset(KEYFRAME)
    sim.set_state(crouched_start(robot), np.zeros(robot.nv))
    wb = g1_whole_body(robot)
    wb.hold(sim.read_state())
    c0 = wb.com.target
    sim.forward()
    feet = [sim.site_pose(f)[0] for f in FEET]
    home = np.array([*(0.5 * (feet[0] + feet[1]))[:2], c0[2]])
    home[0] += float(np.mean([p[0] for p in wb.controller.contacts[FEET[0]].contact.points_F]))
    reader = ImuReader(sim, G1_IMU, noise_scale=imu_noise, seed=seed)
    q0 = sim.read_state().q
    estimator = g1_estimator(robot, (float(q0[0]), float(q0[1])))
    estimator.reset(reader.proprioception())
    w, amplitude = 2 * np.pi * SQUAT_FREQUENCY_HZ, SQUAT_AMPLITUDE_M

    def squat(t: float, state: RobotState) -> None:
        """The CoM over the soles' centre in ``STAND_S``, then down and up (t [s] since the start)."""
        t_squat = max(0.0, t - STAND_S)
        p, v, a = minimum_jerk_at(c0, home, t, 0.0, STAND_S)
        wb.com.set_target(p - [0, 0, amplitude * (1 - np.cos(w * t_squat))],
                          v - [0, 0, amplitude * w * np.sin(w * t_squat)],
                          a - [0, 0, amplitude * w * w * np.cos(w * t_squat)])

    comparison = _Comparison(sim, reader, estimator)
    run(sim, Scheduled(wb.controller, squat), None, seconds, on_step=comparison.on_step)
    errors = comparison.errors
    slip = float(np.linalg.norm((sim.site_pose(FEET[0])[0] - feet[0])[:2]))
    return EstimatorCheck(max(errors), errors[-1], max(comparison.angles), float(np.ptp(comparison.z)), slip,
                          float(np.median(comparison.update_s)) * 1e6)


class _Comparison:
    """Each control cycle (the loop's ``on_step``, the plant stepped): the estimate against the plant.

    Attributes:
        errors: |p_est - p_true| [m] of the base, one per cycle.
        angles: Angle [deg] between the estimated and the true base rotation, one per cycle.
        z: The plant's base height [m], one per cycle.
        update_s: Wall time [s] of each estimator update.
    """

    def __init__(self, sim: Simulator, reader: ImuReader, estimator: LegKinematicsEstimator):
        self.sim, self.reader, self.estimator = sim, reader, estimator
        self.errors: list[float] = []
        self.angles: list[float] = []
        self.z: list[float] = []
        self.update_s: list[float] = []

    def on_step(self, k: int, state: RobotState, reference: object, command: Command) -> bool:
        """Update the estimator from the plant's sensors after cycle ``k``; compare with the truth."""
        t0 = time.perf_counter()
        q_base, _ = self.estimator.update(self.reader.proprioception())
        self.update_s.append(time.perf_counter() - t0)
        truth = self.sim.read_state()
        self.errors.append(float(np.linalg.norm(q_base[:3] - truth.q[:3])))
        R_err = pin.Quaternion(q_base[3:7]).matrix().T @ pin.Quaternion(truth.q[3:7]).matrix()
        self.angles.append(float(np.degrees(np.linalg.norm(pin.log3(R_err)))))
        self.z.append(float(truth.q[2]))
        return False
