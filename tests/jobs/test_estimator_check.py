"""The leg-kinematics estimator in closed loop: a G1 squat under whole-body control, against the plant."""

from __future__ import annotations

from mbctl.jobs.estimator_check import squat_check


def test_estimate_follows_the_plant_through_a_squat(g1_torque):
    check = squat_check(g1_torque, 2.0)  # 1 s standing, then down to the bottom of the squat
    assert check.base_z_range_m > 0.1  # it did squat (the base moves ~0.2 m)
    assert check.position_error_max_m < 5e-3 and check.orientation_error_max_deg < 0.5


def test_estimate_with_the_models_imu_noise(g1_torque):
    check = squat_check(g1_torque, 1.5, imu_noise=1.0)
    assert check.position_error_max_m < 5e-3 and check.orientation_error_max_deg < 0.5
