"""Every numbered example runs as a short subprocess, exits 0 and prints its key figure in bounds.

The examples are standalone scripts (not importable modules: their names start with digits), so
they run the way a user runs them: ``python examples/NN_name.py --duration <short>``. The G1
examples take the ``g1`` fixture: skipped when the model is absent, failed in CI.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import mbctl

EXAMPLES = Path(mbctl.__file__).resolve().parent / "examples"
NUMBER = r"([-+]?\d+(?:\.\d*)?(?:e[-+]?\d+)?)"


def _run(name: str, *args: str, expect: int = 0) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, MPLBACKEND="Agg")
    out = subprocess.run([sys.executable, str(EXAMPLES / name), *args], capture_output=True,
                         text=True, timeout=120, env=env)
    assert out.returncode == expect, out.stdout + out.stderr
    assert "Traceback" not in out.stderr, out.stderr
    return out


def _figure(pattern: str, text: str) -> float:
    match = re.search(pattern.replace("{n}", NUMBER), text)
    assert match, f"{pattern!r} not in:\n{text}"
    return float(match.group(1))


def test_every_example_is_tested_and_listed():
    scripts = sorted(p.name for p in EXAMPLES.glob("[0-9][0-9]_*.py"))
    assert scripts == [
        "01_load_and_step.py", "02_pd_hold.py", "03_computed_torque_square.py",
        "04_g1_joint_step.py", "05_crosscheck_your_robot.py", "06_g1_whole_body_ik.py",
        "07_g1_whole_body_control.py", "08_arm_tool_pose.py", "09_identify_your_arm.py",
        "10_g1_over_dds.py", "11_g1_walk.py",
    ]
    readme = (EXAMPLES / "README.md").read_text()
    for script in scripts:
        assert f"`{script}`" in readme
        text = (EXAMPLES / script).read_text()
        assert "--duration" in text and "Run::" in text


def test_01_load_and_step():
    out = _run("01_load_and_step.py", "--duration", "0.1").stdout
    assert "actuator 'shoulder': position on joint 'shoulder'" in out
    assert _figure(r"engine difference: {n} m", out) < 1e-9


def test_02_pd_hold():
    out = _run("02_pd_hold.py", "--duration", "1.0").stdout
    assert _figure(r"my controller vs the library: {n} rad", out) < 1e-9
    assert _figure(r"steady-state error: {n} mrad", out) < 1e-2
    assert _figure(r"JointPD \(no g\)\s+final error .* max {n} mrad", out) > 10.0  # the sag


def test_03_computed_torque_square():
    out = _run("03_computed_torque_square.py", "--duration", "0.5").stdout
    assert _figure(r"RMS {n} mm", out) < 1.0
    assert _figure(r"max {n} mm", out) < 1.0


def test_04_g1_joint_step(g1):
    out = _run("04_g1_joint_step.py", "--duration", "0.1").stdout
    assert _figure(r"target \+1\.38000 rad, final {n} rad", out) == pytest.approx(1.38, abs=5e-3)
    assert _figure(r"pelvis height: before [\d.]+ m, final {n} m", out) > 0.7
    assert "sensor imu-pelvis-angular-velocity:" in out


def test_04_without_the_g1_exits_2_with_the_loaders_message(tmp_path):
    missing = tmp_path / "unitree_g1"
    out = _run("04_g1_joint_step.py", "--duration", "0.1", "--model-dir", str(missing), expect=2)
    assert out.stdout == ""
    assert "does not exist" in out.stderr and str(missing) in out.stderr


def test_05_crosscheck_built_in_robot():
    out = _run("05_crosscheck_your_robot.py", "--duration", "0.1", "--states", "20").stdout
    assert "3 joints: shoulder (ball), elbow (hinge), extend (slide)" in out
    assert "result: PASS" in out
    assert _figure(r"position difference {n} m at 'tool'", out) < 1e-9


def test_05_crosscheck_a_robot_file():
    assets = Path(mbctl.__file__).resolve().parent / "robots" / "assets"
    out = _run("05_crosscheck_your_robot.py", "--duration", "0.1", "--states", "10",
               "--robot", str(assets / "two_link_arm.xml"), "--scene", str(assets / "two_link.xml")).stdout
    assert "result: PASS" in out


def test_06_g1_whole_body_ik(g1):
    out = _run("06_g1_whole_body_ik.py", "--duration", "0.1").stdout
    assert _figure(r"left_palm: .*residual in MuJoCo {n} mm", out) < 1.0
    assert _figure(r"right_palm: .*residual in MuJoCo {n} mm", out) < 1.0


def test_07_g1_whole_body_control(g1):
    out = _run("07_g1_whole_body_control.py", "--duration", "1").stdout
    assert _figure(r"CoM RMS error \(MuJoCo's CoM\): {n} mm", out) < 5.0
    assert _figure(r"QP vs MuJoCo vertical foot force: {n} %", out) < 5.0


def test_08_arm_tool_pose_shipped_arm():
    out = _run("08_arm_tool_pose.py").stdout  # the whole trajectory: ~1.2 s simulated
    assert "IK: converged True" in out
    assert _figure(r"in MuJoCo the tool is {n} mm", out) < 0.1
    assert _figure(r"tool RMS {n} mm from the planned path", out) < 1.0
    assert _figure(r"final {n} mm from the target", out) < 1.0
    assert _figure(r"ruckig: {n} s", out) > 0.2


#: A user's 7-dof arm, unlike ours: default classes, a rotated root (hanging from a gantry),
#: position actuators (the example converts them to motors), a gripper site named differently;
#: its scene adds a floor, a gantry beam and a free box on the floor.
USER_ARM = """<mujoco model="user_arm7">
  <compiler angle="radian" autolimits="true"/>
  <default>
    <default class="link"><geom type="capsule" size="0.035" density="800"/></default>
    <default class="j"><joint axis="0 0 1"/></default>
    <joint armature="0.02" damping="0.5" range="-2.9 2.9"/>
    <position kp="200" dampratio="1" forcerange="-120 120" ctrlrange="-2.9 2.9"/>
  </default>
  <worldbody>
    <body name="mount" pos="0 0 1.6" quat="0 1 0 0">
      <body name="l1"><joint class="j" name="j1"/>
        <geom class="link" fromto="0 0 0 0 0 0.15"/>
      <body name="l2" pos="0 0 0.15"><joint name="j2" axis="0 1 0"/>
        <geom class="link" fromto="0 0 0 0 0 0.3"/>
      <body name="l3" pos="0 0 0.3"><joint class="j" name="j3"/>
        <geom class="link" fromto="0 0 0 0 0 0.1"/>
      <body name="l4" pos="0 0 0.1"><joint name="j4" axis="0 1 0"/>
        <geom class="link" fromto="0 0 0 0 0 0.3"/>
      <body name="l5" pos="0 0 0.3"><joint class="j" name="j5"/>
        <geom class="link" fromto="0 0 0 0 0 0.1"/>
      <body name="l6" pos="0 0 0.1"><joint name="j6" axis="0 1 0"/>
        <geom class="link" fromto="0 0 0 0 0 0.08"/>
      <body name="l7" pos="0 0 0.08"><joint class="j" name="j7"/>
        <geom class="link" fromto="0 0 0 0 0 0.05"/>
        <site name="gripper" pos="0 0 0.08"/>
      </body></body></body></body></body></body></body>
    </body>
  </worldbody>
  <actuator>
    <position joint="j1"/><position joint="j2"/><position joint="j3"/><position joint="j4"/>
    <position joint="j5"/><position joint="j6"/><position joint="j7"/>
  </actuator>
  <keyframe><key name="ready" qpos="0 0.5 0 1.2 0 0.6 0"/></keyframe>
</mujoco>"""
USER_SCENE = """<mujoco model="user scene">
  <include file="arm7.xml"/>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    <geom name="beam" type="box" size="0.6 0.05 0.05" pos="0 0 1.66"/>
    <body name="box" pos="0.5 0.3 0.05"><freejoint/><geom type="box" size="0.05 0.05 0.05"/></body>
  </worldbody>
</mujoco>"""


def test_08_arm_tool_pose_on_a_users_arm_and_scene(tmp_path):
    (tmp_path / "arm7.xml").write_text(USER_ARM)
    (tmp_path / "scene.xml").write_text(USER_SCENE)
    out = _run("08_arm_tool_pose.py", "--robot", str(tmp_path / "arm7.xml"), "--scene",
               str(tmp_path / "scene.xml"), "--tool", "gripper", "--keyframe", "ready",
               "--offset", "0.05,-0.1,0.1", "--yaw", "-20").stdout
    assert "converted to torque motors" in out and "Robot('arm7', nq=7, nv=7, nu=7)" in out
    assert _figure(r"in MuJoCo the tool is {n} mm", out) < 0.1
    assert _figure(r"final {n} mm from the target", out) < 1.0
    bad = _run("08_arm_tool_pose.py", "--robot", str(tmp_path / "arm7.xml"), "--keyframe", "ready",
               "--tool", "hand", expect=2)
    assert "Unknown frame 'hand'" in bad.stderr and "gripper" in bad.stderr


def test_09_identify_your_arm():
    out = _run("09_identify_your_arm.py", "--duration", "6").stdout
    assert _figure(r"largest base-parameter error {n} \(bound 0.01\): ok", out) < 0.01
    assert "identified.xml: cross-check PASS" in out


def _processes_with(*args: str) -> list[str]:
    """Command lines of this machine's processes that contain ``args`` in a row."""
    needle = "\0".join(args) + "\0"
    found = []
    for proc in Path("/proc").glob("[0-9]*"):
        try:
            cmdline = (proc / "cmdline").read_bytes().decode(errors="replace")
        except OSError:
            continue
        if needle in cmdline:
            found.append(cmdline.replace("\0", " "))
    return found


def test_10_g1_over_dds(g1, dds_domain):
    """The same controller in-process and over DDS (its own bridge on lo, stopped at the end)."""
    out = _run("10_g1_over_dds.py", "--duration", "1", "--domain", str(dds_domain),
               "--watchdog-periods", "50").stdout  # 2 shared cores: a stall is not a lost link here
    in_process = _figure(r"CoM RMS error \[mm\]\s+{n}", out)
    over_dds = _figure(r"CoM RMS error \[mm\]\s+[\d.]+\s+{n}", out)
    assert in_process < 5.0 and over_dds < 5.0
    assert abs(over_dds - in_process) < 1.0  # measured 0.15 mm (2 s squat)
    assert re.search(r"fell\s+no\s+no", out) and re.search(r"cycles\s+500\s+500", out)
    assert _processes_with("serve", "g1", "--start", "crouched", "--domain", str(dds_domain)) == []


def test_11_g1_walk(g1):
    out = _run("11_g1_walk.py", "--duration", "3").stdout
    assert "fell: no" in out
    assert _figure(r"walked [\d.]+ s: {n} steps", out) >= 3
    assert 0.4 < _figure(r"pelvis moved {n} m", out) < 0.9  # 0.3 m/s from the first step at 0.8 s
