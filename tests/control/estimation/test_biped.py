"""The leg-kinematics estimator on a small biped built in code, against MuJoCo's truth.

The biped: a floating pelvis with an IMU site (rotated in the pelvis, so R_BI matters), two legs of
three pitch hinges (hip, knee, ankle) ending in box feet with a site at each sole's centre, stiff
position actuators. It stands, then squats (feet flat, the pelvis going up and down). Each control
step runs as the DDS bridge runs it and the estimator gets what the DDS interface hands it: the
joints' q and dq of the state the step starts from and the IMU's quaternion, gyro and
accelerometer, as float32 (the LowState wire format), in a
:class:`~mbctl.robots.interface.Proprioception` (hardware/ builds it the same way from the message).

The plant integrates with MuJoCo's semi-implicit Euler, not implicitfast: implicitfast moves the
base by an acceleration that differs from what its accelerometer reports (the explicit qacc) by up
to 0.12 m/s^2 here, with these stiff actuators; that, not the estimator, would set the error of
dead reckoning. With Euler the two agree to 2 mm/s^2 (the IMU's lever arm).

The G1 on the same estimator: tests/control/estimation/test_leg_kinematics.py and
tests/jobs/test_estimator_check.py.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pinocchio as pin
import pytest

from mbctl.control.estimation import LegKinematicsEstimator
from mbctl.robots import Robot, load_robot
from mbctl.robots.commands import position_target
from mbctl.robots.interface import ImuReading, ImuSpec, Proprioception
from mbctl.sim.imu import ImuReader
from mbctl.sim.simulator import Simulator

THIGH_M = SHIN_M = 0.3  # [m]
JOINTS = [f"{side}_{joint}" for side in ("l", "r") for joint in ("hip", "knee", "ankle")]
IMU = ImuSpec(site="imu", gyro="imu_gyro", accelerometer="imu_accel")
FEET = ("l_sole", "r_sole")
CROUCH_RAD = 0.4  # the squat's angle phi at rest: hip -phi, knee 2 phi, ankle -phi (feet flat)
SETTLE_S = 0.5


def _leg(side: str, y: float) -> str:
    return f"""
      <body name="{side}_thigh" pos="0 {y} -0.05">
        <joint name="{side}_hip" axis="0 1 0" range="-1.5 1.5"/>
        <inertial pos="0 0 -0.15" mass="2" diaginertia="0.02 0.02 0.003"/>
        <body name="{side}_shin" pos="0 0 -{THIGH_M}">
          <joint name="{side}_knee" axis="0 1 0" range="0 2.5"/>
          <inertial pos="0 0 -0.15" mass="1.5" diaginertia="0.015 0.015 0.002"/>
          <body name="{side}_foot" pos="0 0 -{SHIN_M}">
            <joint name="{side}_ankle" axis="0 1 0" range="-1.5 1.5"/>
            <inertial pos="0.02 0 -0.02" mass="0.5" diaginertia="0.001 0.002 0.002"/>
            <geom type="box" size="0.09 0.04 0.01" pos="0.02 0 -0.03" contype="1" conaffinity="1"/>
            <site name="{side}_sole" pos="0.02 0 -0.04"/>
          </body>
        </body>
      </body>"""


BIPED_XML = f"""
<mujoco model="estimator_biped">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="0.002" integrator="Euler"/>
  <default>
    <joint damping="0.5" armature="0.01"/>
    <geom contype="0" conaffinity="0" friction="1"/>
    <position kp="600" kv="30" ctrlrange="-2.5 2.5"/>
  </default>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1" contype="1" conaffinity="1"/>
    <body name="pelvis" pos="0 0 0.7">
      <freejoint name="root"/>
      <inertial pos="0.02 0 0.08" mass="10" diaginertia="0.12 0.1 0.08"/>
      <site name="imu" pos="0.03 0.01 0.06" euler="0.1 -0.2 0.3"/>
      {_leg("l", 0.1)}
      {_leg("r", -0.1)}
    </body>
  </worldbody>
  <actuator>{"".join(f'<position name="{j}" joint="{j}"/>' for j in JOINTS)}</actuator>
  <sensor>
    <gyro name="imu_gyro" site="imu" noise="0.01"/>
    <accelerometer name="imu_accel" site="imu" noise="0.1"/>
  </sensor>
</mujoco>
"""


@pytest.fixture(scope="module")
def biped(tmp_path_factory) -> Robot:
    path = tmp_path_factory.mktemp("estimator_biped") / "biped.xml"
    path.write_text(BIPED_XML)
    return load_robot(path)


def _crouch(phi: float) -> np.ndarray:
    """The joint targets (6,) [rad] of the squat at angle ``phi``: each ankle under its hip, feet flat."""
    return np.array([-phi, 2.0 * phi, -phi] * 2)


def _standing_q(robot: Robot) -> np.ndarray:
    """Crouched at ``CROUCH_RAD``, the soles on the floor."""
    q = robot.neutral_q()
    q[7:] = _crouch(CROUCH_RAD)
    model = robot.pin_model
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    q[2] -= data.oMf[model.getFrameId("l_sole")].translation[2]
    return q


def _over_the_wire(reading: Proprioception) -> Proprioception:
    """``reading`` as the DDS interface receives it: every value through float32 (LowState's ``<f4``)."""

    def f32(a: np.ndarray) -> np.ndarray:
        return np.asarray(a, dtype=np.float32).astype(float)

    imu = reading.imu
    return Proprioception(reading.time_s, f32(reading.q_joints), f32(reading.v_joints),
                          ImuReading(f32(imu.quat_wxyz), f32(imu.gyro_I), f32(imu.accel_I)))


class Run(NamedTuple):
    """Errors of the estimate against the plant, and how much the base moved."""

    position_error_m: np.ndarray  # (steps, 3) p_est - p_true in W
    velocity_error_m_s: np.ndarray  # (steps, 3) v_est - v_true in B
    orientation_error_rad: float  # largest angle between the estimated and true R_WB
    angular_velocity_error_rad_s: float  # largest |w_est - w_true| (inf-norm), in B
    base_z_range_m: float
    base_speed_max_m_s: float
    foot_slip_m: float  # how far the soles moved on the floor in the plant (the filter assumes 0)


def _run(robot: Robot, seconds: float, squat_amplitude_rad: float = 0.0, squat_hz: float = 0.5,
         imu_noise: float = 0.0, legs_off_s: tuple[float, float] | None = None) -> Run:
    """Settle, reset the estimator, then stand or squat ``phi = CROUCH + A (1 - cos 2 pi f t)``.

    Args:
        legs_off_s: A window [s] in which the estimator is told no foot touches the ground: the
            IMU alone carries the estimate then.
    """
    sim = Simulator(robot)
    sim.reset(q=_standing_q(robot))
    sim.step(position_target(_crouch(CROUCH_RAD)), int(round(SETTLE_S / sim.control_period_s)))
    reader = ImuReader(sim, IMU, noise_scale=imu_noise, seed=7)
    truth = sim.read_state()
    soles = [sim.site_pose(foot)[0].copy() for foot in FEET]
    # W as the estimator defines it: where the base started, the ground at the soles' height (they
    # sink 0.35 mm into MuJoCo's soft floor, an offset the filter cannot know)
    estimator = LegKinematicsEstimator(robot, {foot: np.zeros(3) for foot in FEET}, IMU.site,
                                       start_xy_m=(float(truth.q[0]), float(truth.q[1])),
                                       ground_z_m=float(np.mean([p[2] for p in soles])))
    estimator.reset(_over_the_wire(reader.proprioception()))
    dp, dv, angles, dw, z, speed = [], [], [], [], [], []
    for k in range(int(round(seconds / sim.control_period_s))):
        t = k * sim.control_period_s
        phi = CROUCH_RAD + squat_amplitude_rad * (1.0 - np.cos(2.0 * np.pi * squat_hz * t))
        # one period as the DDS bridge runs it (sim/dds_bridge.py): the command in, the state the
        # step starts from out, with the IMU of that state and the accelerometer of that step
        sim.send(position_target(_crouch(phi)))
        sim.step_begin()
        truth = sim.read_state()
        sim.step_end()
        reading = Proprioception(truth.time_s, truth.q[7:], truth.v[6:], reader.imu(forward=False))
        if legs_off_s is not None:
            estimator.set_contacts(dict.fromkeys(FEET, not legs_off_s[0] <= t < legs_off_s[1]))
        q_base, v_base = estimator.update(_over_the_wire(reading))
        dp.append(q_base[:3] - truth.q[:3])
        dv.append(v_base[:3] - truth.v[:3])
        R_err = pin.Quaternion(q_base[3:7]).matrix().T @ pin.Quaternion(truth.q[3:7]).matrix()
        angles.append(float(np.linalg.norm(pin.log3(R_err))))
        dw.append(float(np.abs(v_base[3:] - truth.v[3:6]).max()))
        z.append(float(truth.q[2]))
        speed.append(float(np.linalg.norm(truth.v[:3])))
    slip = max(float(np.linalg.norm(sim.site_pose(foot)[0][:2] - p[:2]))
               for foot, p in zip(FEET, soles, strict=True))
    return Run(np.array(dp), np.array(dv), max(angles), max(dw), float(np.ptp(z)), max(speed), slip)


def _report(run: Run) -> str:
    return (f"|dp|max {np.abs(run.position_error_m).max(axis=0)} m, "
            f"|dv|max {np.abs(run.velocity_error_m_s).max(axis=0)} m/s, "
            f"angle {run.orientation_error_rad:.1e} rad, dw {run.angular_velocity_error_rad_s:.1e} rad/s, "
            f"z range {run.base_z_range_m:.4f} m, speed max {run.base_speed_max_m_s:.3f} m/s, "
            f"slip {run.foot_slip_m:.1e} m")


def test_standing_the_estimate_stays_on_the_plants_base(biped):
    run = _run(biped, seconds=1.0)
    print(_report(run))
    # measured: |dp| 3.7e-7 m, |dv| 2.0e-5 m/s (the first update, the settling's last sway)
    assert np.abs(run.position_error_m).max() < 5e-5
    assert np.abs(run.velocity_error_m_s).max() < 1e-4
    # orientation and angular velocity are the IMU's through R_BI, exact to float32 (measured
    # 2.4e-8 rad, 1.5e-11 rad/s); without R_BI (the IMU site is rotated 0.37 rad) they are off by 0.37 rad
    assert run.orientation_error_rad < 1e-6
    assert run.angular_velocity_error_rad_s < 1e-6


def test_squatting_the_estimate_follows_the_plants_base(biped):
    # one squat at 0.5 Hz, phi 0.4 -> 0.6 rad: the pelvis goes 5.9 cm down and up at up to 9.3 cm/s
    run = _run(biped, seconds=2.0, squat_amplitude_rad=0.1)
    print(_report(run))
    assert run.base_z_range_m > 0.05 and run.base_speed_max_m_s > 0.08  # the base really moved
    assert run.foot_slip_m < 1e-4  # and the feet did not (measured 9 um: the filter's assumption holds)
    # measured: |dp| 2.6e-5 m, |dv| 8.7e-5 m/s; bounds ~3x those, 1/580 and 1/370 of the motion. The
    # filter without its legs' velocity rows errs by 3.7e-4 m/s, without w_B x p_BP in them by 3.3e-3 m/s
    assert np.abs(run.position_error_m).max() < 1e-4
    assert np.abs(run.velocity_error_m_s).max() < 2.5e-4
    assert run.orientation_error_rad < 1e-6


def test_with_no_foot_in_contact_the_imu_carries_the_estimate(biped):
    # told that no foot touches the ground for 0.4 s of the squat (its fastest part), the filter
    # dead-reckons on the accelerometer alone
    run = _run(biped, seconds=2.0, squat_amplitude_rad=0.1, legs_off_s=(0.4, 0.8))
    print(_report(run))
    # measured: |dv| 8.2e-4 m/s, |dp| 1.0e-4 m (the IMU's lever arm, out of the filter's scope: the
    # pelvis's pitch acceleration 0.04 rad/s^2 x 7 cm, 3 mm/s^2 for 0.4 s); an accelerometer read as
    # if the robot were at rest gives 1.9e-2 m/s and 5.1e-3 m
    assert np.abs(run.velocity_error_m_s).max() < 3e-3
    assert np.abs(run.position_error_m).max() < 5e-4


def test_squatting_with_the_declared_imu_noise(biped):
    # the sensors' declared noise (gyro 0.01 rad/s, accelerometer 0.1 m/s^2, white): the gyro's enters
    # the legs' velocity as w_B x p_BP, 0.01 rad/s x 0.55 m = 5.5 mm/s on x and y each sample, the
    # same for both feet (one gyro), and the filter (leg velocity 0.02 m/s vs accelerometer 0.5 m/s^2
    # noise models) passes most of it. Measured over seeds 0-9: rms |dv| 6.7-7.0 mm/s, max |dv|
    # 13-20 mm/s (20 with this seed, 7), max |dp| 0.18 mm.
    run = _run(biped, seconds=2.0, squat_amplitude_rad=0.1, imu_noise=1.0)
    print(_report(run))
    rms = float(np.sqrt(np.mean(np.sum(run.velocity_error_m_s**2, axis=1))))
    assert rms < 1e-2
    assert np.abs(run.velocity_error_m_s).max() < 3e-2
    assert np.abs(run.position_error_m).max() < 1e-3
