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
        "07_g1_whole_body_control.py", "08_identify_your_arm.py",
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


def test_08_identify_your_arm():
    out = _run("08_identify_your_arm.py", "--duration", "6").stdout
    assert _figure(r"largest base-parameter error {n} \(bound 0.01\): ok", out) < 0.01
    assert "identified.xml: cross-check PASS" in out
