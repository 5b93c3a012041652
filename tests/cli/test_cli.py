"""The command line, run as a user would: exit codes and messages."""

from __future__ import annotations

import json

import pytest

from tests.conftest import run_mbctl


def test_verify_two_link():
    out = run_mbctl("verify", "two_link")
    assert out.returncode == 0, out.stderr
    assert "5 passed, 0 failed" in out.stdout
    assert "[PASS] 100 steps give 0.2 s" in out.stdout


def test_robots_lists_sources():
    out = run_mbctl("robots")
    assert out.returncode == 0
    assert "g1" in out.stdout and "Menagerie" in out.stdout


def test_unknown_robot_exits_nonzero_with_matches():
    out = run_mbctl("inspect", "two_lnk")
    assert out.returncode == 2
    assert "Did you mean 'two_link'" in out.stderr
    assert "Traceback" not in out.stderr


def test_inspect_g1_side_by_side(g1):
    out = run_mbctl("inspect", "g1")
    assert out.returncode == 0, out.stderr
    assert "nq                          36          36" in out.stdout
    assert "left_knee_joint" in out.stdout and "position" in out.stdout
    assert "imu-pelvis-angular-velocity" in out.stdout


def test_joint_step_cli_g1(g1, tmp_path):
    out = run_mbctl("joint-step", "g1", "--joint", "left_elbow_joint", "--delta", "0.1", "--steps", "250",
                    "--keyframe", "stand", "--output", str(tmp_path))
    assert out.returncode == 0, out.stderr
    assert "target +1.38000 rad" in out.stdout
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["run"]["steps"] == 250 and report["status"] == "completed"


@pytest.mark.parametrize(
    "args, message",
    [
        (["--joint", "left_elbo_joint"], "Did you mean 'left_elbow_joint'"),
        (["--joint", "left_elbow_joint", "--keyframe", "stnd"], "Did you mean 'stand'"),
    ],
)
def test_joint_step_cli_bad_names(g1, tmp_path, args, message):
    out = run_mbctl("joint-step", "g1", "--delta", "0.1", "--steps", "5", "--output", str(tmp_path), *args)
    assert out.returncode == 2
    assert message in out.stderr


def test_g1_missing_offline_says_how(tmp_path):
    out = run_mbctl("inspect", "g1", env={"MENAGERIE_ROOT": str(tmp_path)})
    assert out.returncode == 2
    assert "MENAGERIE_ROOT" in out.stderr and "unitree_g1" in out.stderr


def test_tampered_model_names_the_file(g1, tmp_path):
    import shutil
    from pathlib import Path

    root = tmp_path / "root"
    shutil.copytree(Path(g1.source.robot_file).parent, root / "unitree_g1")
    with open(root / "unitree_g1" / "scene.xml", "a") as f:
        f.write("\n")
    out = run_mbctl("inspect", "g1", env={"MENAGERIE_ROOT": str(root)})
    assert out.returncode == 2
    assert "scene.xml fails its SHA-256 check" in out.stderr


@pytest.mark.parametrize(("args", "message"), [
    (["push", "--push-hold", "-0.1"], "push_hold must be a finite time > 0 s; got -0.1"),
    (["push", "--push-hold", "nan"], "push_hold must be a finite time > 0 s; got nan"),
    (["forward", "--push-hold", "0.08"], "--push-hold applies to the push scenario only"),
])
def test_g1_walk_push_hold_bad_input_exits_2_naming_it(tmp_path, args, message):
    out = run_mbctl("g1-walk", *args, "--output", str(tmp_path / "out"))
    assert out.returncode == 2, out.stderr
    assert message in out.stderr and "Traceback" not in out.stderr
