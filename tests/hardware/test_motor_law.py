"""The delayed motor law's stability (hardware/motor_law.py) against MuJoCo running that law."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mbctl.hardware.motor_law import (
    GAIN_MARGIN,
    GAIN_STEP,
    inverse_inertia,
    least_stable_mode,
    stabilize,
    stable_gains,
)
from mbctl.robots import load_robot
from mbctl.unitree.motors import MotorMap

#: One hinge of 0.0104 kg m^2 (the G1's wrist roll), no gravity, a motor with room to diverge.
HINGE = """<mujoco><option timestep="{dt}" gravity="0 0 0"/><worldbody><body>
<joint name="j" type="hinge" armature="0.0104"/><geom type="sphere" size="0.001" mass="1e-6"/>
</body></worldbody><actuator><motor joint="j" ctrlrange="-1e6 1e6"/></actuator>
<sensor><jointpos joint="j"/><jointvel joint="j"/></sensor></mujoco>"""

#: Two hinges in series (a heavy upper link, a light lower one), gravity off: the links couple.
CHAIN = """<mujoco><option timestep="{dt}" gravity="0 0 0"/><worldbody>
<body name="upper"><joint name="a" type="hinge" axis="0 0 1" armature="0.01"/>
<geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="2"/>
<body name="lower" pos="0.3 0 0"><joint name="b" type="hinge" axis="0 0 1" armature="0.002"/>
<geom type="capsule" fromto="0 0 0 0.1 0 0" size="0.01" mass="0.05"/></body></body></worldbody>
<actuator><motor joint="a" ctrlrange="-1e6 1e6"/><motor joint="b" ctrlrange="-1e6 1e6"/></actuator>
<sensor><jointpos joint="a"/><jointpos joint="b"/><jointvel joint="a"/><jointvel joint="b"/></sensor>
</mujoco>"""


def _run_delayed_law(xml: str, kp: np.ndarray, kd: np.ndarray, steps: int) -> np.ndarray:
    """|q| per step of MuJoCo under Unitree's simulator's law: the torque from the sensors after the
    step before (those of the state before it), held for the step. A diverged run (MuJoCo resets
    its state on a huge acceleration) is padded with inf."""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    n = model.nu
    data.qpos[:] = 0.01
    mujoco.mj_forward(model, data)
    amplitude = []
    for _ in range(steps):
        data.ctrl[:] = -kp * data.sensordata[:n] - kd * data.sensordata[n:2 * n]
        mujoco.mj_step(model, data)
        if data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number:
            return np.asarray(amplitude + [np.inf] * (steps - len(amplitude)))
        amplitude.append(np.abs(data.qpos).max())
    return np.asarray(amplitude)


def _decay_per_step(amplitude: np.ndarray) -> float:
    """The envelope's ratio per step over the run's second half."""
    half = amplitude.size // 2
    return float((amplitude[-20:].max() / amplitude[half - 20:half].max()) ** (1.0 / (amplitude.size - half)))


@pytest.mark.parametrize(("kp", "kd"), [(100.0, 1.0), (50.0, 0.5), (30.0, 1.0)])
def test_one_joint_decays_in_mujoco_at_the_predicted_rate(kp, kd):
    dt = 0.005
    size, _ = least_stable_mode(np.array([[1 / 0.0104]]), np.array([kp]), np.array([kd]), dt)
    measured = _decay_per_step(_run_delayed_law(HINGE.format(dt=dt), np.array([kp]), np.array([kd]), 300))
    assert size < 1 and measured == pytest.approx(size, abs=2e-3)


def test_the_model_s_wrist_gains_diverge_at_5_ms_and_the_lowered_ones_do_not():
    dt, w = 0.005, np.array([[1 / 0.0104]])
    kp, kd = np.array([500.0]), np.array([4.55])  # Menagerie's G1 wrist roll
    assert least_stable_mode(w, kp, kd, dt)[0] > 1.5
    assert _run_delayed_law(HINGE.format(dt=dt), kp, kd, 60)[-1] > 1.0  # from 0.01 rad
    k, d = stable_gains(w, kp, kd, dt)
    assert k[0] < kp[0] and d[0] < kd[0] and d[0] / k[0] == pytest.approx(kd[0] / kp[0])
    assert least_stable_mode(w, GAIN_MARGIN * k, GAIN_MARGIN * d, dt)[0] < 1.0
    assert _run_delayed_law(HINGE.format(dt=dt), k, d, 400)[-1] < 1e-3


def test_coupled_joints_each_stable_alone_diverge_together_and_the_rule_sees_it(tmp_path):
    """Each joint's gains are stable with the other locked, yet the chain diverges in MuJoCo: the
    rule judges the coupled law, and its gains decay in MuJoCo."""
    dt = 0.004
    (tmp_path / "chain.xml").write_text(CHAIN.format(dt=dt))
    robot = load_robot(tmp_path / "chain.xml")
    w = inverse_inertia(robot, np.zeros(2), [0, 1])
    kp, kd = np.array([40.0, 30.0]), np.array([0.4, 0.15])
    locked = 1.0 / np.diag(np.linalg.inv(w))  # each joint with the other locked
    for j in range(2):
        alone = least_stable_mode(np.array([[1 / locked[j]]]), kp[j:j + 1], kd[j:j + 1], dt)[0]
        assert alone < 1.0
    assert least_stable_mode(w, kp, kd, dt)[0] > 1.0
    assert _run_delayed_law(CHAIN.format(dt=dt), kp, kd, 1500)[-1] > 0.1
    k, d = stable_gains(w, kp, kd, dt)
    assert np.all(k <= kp) and np.any(k < kp)
    assert _decay_per_step(_run_delayed_law(CHAIN.format(dt=dt), k, d, 1500)) < 1.0


@settings(max_examples=60, deadline=None)
@given(st.floats(1.0, 1000.0), st.floats(0.0, 20.0), st.floats(1e-3, 1.0), st.sampled_from([0.002, 0.005]))
def test_one_joint_s_mode_is_the_largest_root_of_its_cubic(kp, kd, inertia, dt):
    a = dt / inertia
    roots = np.roots([1.0, -2.0, 1.0 + a * (kp * dt + kd), -a * kd])
    size, _ = least_stable_mode(np.array([[1 / inertia]]), np.array([kp]), np.array([kd]), dt)
    assert size == pytest.approx(np.abs(roots).max(), rel=1e-6, abs=1e-9)


def test_gains_with_margin_are_kept_and_nan_stays_nan():
    w = np.diag([1 / 0.5, 1 / 0.0104, 1 / 0.2])
    kp, kd = np.array([100.0, np.nan, 50.0]), np.array([2.0, np.nan, 1.0])
    k, d = stable_gains(w, kp, kd, 0.002)
    assert np.array_equal(k, kp, equal_nan=True) and np.array_equal(d, kd, equal_nan=True)


def test_the_damping_command_keeps_the_largest_stable_kd():
    """kp = 0: the free positions drift (z = 1, not unstable); the velocities' roots count."""
    m, dt = 0.0104, 0.005
    _, d = stable_gains(np.array([[1 / m]]), np.array([0.0]), np.array([5.0]), dt)
    assert 0 < d[0] < 5.0
    assert least_stable_mode(np.array([[1 / m]]), np.array([0.0]), GAIN_MARGIN * d, dt)[0] < 1.0
    # one step back up the rule's ladder is not stable with margin
    assert least_stable_mode(np.array([[1 / m]]), np.array([0.0]), GAIN_MARGIN * d / GAIN_STEP, dt)[0] >= 1.0


def test_feet_on_the_ground_make_the_leg_heavier_and_hold_the_chain_still(g1):
    """With the feet held, a torque cannot move them: J W-like accelerations vanish; the ankle feels
    the body, not the foot."""
    from mbctl.robots.g1 import FEET

    q = g1.keyframe_q("stand")
    motors = MotorMap.for_robot(g1)
    free = inverse_inertia(g1, q, motors.idx_v)
    held = inverse_inertia(g1, q, motors.idx_v, FEET)
    ankle = motors.joints.index("left_ankle_pitch_joint")
    assert 1 / held[ankle, ankle] > 10 * (1 / free[ankle, ankle])
    wrist = motors.joints.index("left_wrist_roll_joint")
    assert held[wrist, wrist] == pytest.approx(free[wrist, wrist], rel=1e-3)  # far from the feet


def test_stabilize_reports_each_lowered_gain_and_the_g1_at_5_ms_is_stable_with_margin(g1):
    from mbctl.hardware import MotorGains, default_damping
    from mbctl.robots.g1 import FEET

    motors = MotorMap.for_robot(g1)
    gains = MotorGains.from_actuators(g1, motors)
    q = g1.keyframe_q("stand")[motors.idx_q]
    found = stabilize(g1, motors, gains, default_damping(motors), 0.005, q, FEET)
    w = inverse_inertia(g1, g1.keyframe_q("stand"), motors.idx_v, FEET)
    assert least_stable_mode(w, gains.kp, gains.kd, 0.005)[0] > 2.0
    k, d = found.gains.kp, found.gains.kd
    assert least_stable_mode(w, GAIN_MARGIN * k, GAIN_MARGIN * d, 0.005)[0] < 1.0
    for i, joint in enumerate(motors.joints):
        if k[i] != gains.kp[i]:
            assert found.lowered[joint]["kp"] == (gains.kp[i], k[i])
    assert "kp" in found.lowered["left_wrist_roll_joint"]
    assert found.lowered["left_ankle_roll_joint"].keys() == {"damping_kd"}  # stiff on the ground
