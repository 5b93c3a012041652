"""mbctl render, replay, view and --video from the command line (headless, MUJOCO_GL probed)."""

from __future__ import annotations

import os
import subprocess
import sys

import imageio.v3 as iio
from matplotlib import image

ENV = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM", "DISPLAY",
                                                        "WAYLAND_DISPLAY")}


def _mbctl(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "mbctl.cli", *args], capture_output=True, text=True,
                          timeout=180, env=ENV)


def test_demo_video_then_replay_to_mp4(tmp_path):
    run = tmp_path / "demo"
    out = _mbctl("demo", "--duration", "0.5", "--video", "--video-size", "320x240", "--output", str(run),
                 "--quiet")
    assert out.returncode == 0, out.stderr
    assert iio.imread(run / "video.mp4").shape == (15, 240, 320, 3)
    out = _mbctl("replay", str(run), "--video", "--output", str(tmp_path / "again.mp4"))
    assert out.returncode == 0, out.stderr
    assert "16 frames, 0.50 s simulated" in out.stdout
    assert iio.imread(tmp_path / "again.mp4").shape == (16, 480, 640, 3)


def test_render_writes_a_still(tmp_path):
    out = _mbctl("render", "two_link_torque", "--output", str(tmp_path / "arm.png"), "--size", "200x100")
    assert out.returncode == 0, out.stderr
    assert image.imread(tmp_path / "arm.png").shape[:2] == (100, 200)


def test_bad_input_exits_2_with_a_message(tmp_path):
    out = _mbctl("demo", "--video", "--video-size", "640by480", "--output", str(tmp_path / "d"))
    assert out.returncode == 2 and "video size must be WIDTHxHEIGHT in pixels" in out.stderr
    out = _mbctl("view", "two_link")
    assert out.returncode == 2 and "mbctl view needs a display" in out.stderr
    out = _mbctl("replay", str(tmp_path))
    assert out.returncode == 2 and "holds no trajectory.npz" in out.stderr
    out = _mbctl("render", "two_link", "--output", str(tmp_path / "arm.jpg"))
    assert out.returncode == 2 and "--output must be a .png file" in out.stderr
    out = _mbctl("replay", str(tmp_path), "--web", "--video")  # --video was silently ignored
    assert out.returncode == 2 and "replay --web serves the run to the browser and writes no file; " \
        "--video (an MP4) cannot go with it" in out.stderr, out.stderr


def test_replay_of_a_damaged_run_exits_2_naming_the_problem(tmp_path):
    import numpy as np

    from mbctl.robots import load_robot
    from mbctl.sim import Simulator
    from mbctl.sim.trajectory import TrajectoryRecorder

    sim = Simulator(load_robot("two_link_torque"))
    rec = TrajectoryRecorder(sim, tmp_path).attach()
    for _ in range(10):
        sim.step()
    path = rec.close()
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files}
    arrays["qpos"][4, 1] = np.nan
    np.savez(path, **arrays)
    out = _mbctl("replay", str(tmp_path), "--video", "--output", str(tmp_path / "r.mp4"))
    assert out.returncode == 2 and "qpos sample 4 (of 11) holds NaN or inf" in out.stderr, out.stderr
    path.write_bytes(path.read_bytes()[:100])
    out = _mbctl("replay", str(tmp_path), "--video", "--output", str(tmp_path / "r.mp4"))
    assert out.returncode == 2 and "is damaged (truncated or not an npz archive)" in out.stderr, out.stderr
    assert "Traceback" not in out.stderr and not (tmp_path / "r.mp4").exists()


def test_render_and_replay_replace_a_symlink_never_follow_it(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("the user's file")
    (tmp_path / "arm.png").symlink_to(victim)
    out = _mbctl("render", "two_link_torque", "--output", str(tmp_path / "arm.png"), "--size", "64x48")
    assert out.returncode == 0, out.stderr
    assert victim.read_text() == "the user's file" and not (tmp_path / "arm.png").is_symlink()
    assert image.imread(tmp_path / "arm.png").shape[:2] == (48, 64)
    run = tmp_path / "run"
    out = _mbctl("demo", "--duration", "0.1", "--output", str(run), "--quiet")
    assert out.returncode == 0, out.stderr
    (run / "replay.mp4").symlink_to(victim)
    out = _mbctl("replay", str(run), "--video", "--size", "64x48")
    assert out.returncode == 0, out.stderr
    assert victim.read_text() == "the user's file" and not (run / "replay.mp4").is_symlink()
    assert iio.imread(run / "replay.mp4").shape[1:] == (48, 64, 3)


def test_view_web_serves_until_ctrl_c_and_a_damaged_run_exits_2(tmp_path):
    import signal

    args = ["view", "two_link_torque", "--web", "--port", "0"]
    proc = subprocess.Popen([sys.executable, "-m", "mbctl.cli", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=ENV)
    try:
        line = proc.stdout.readline()  # blocks until the server is up (or the command failed)
        assert line.startswith("serving http://127.0.0.1:") and "Ctrl-C stops it" in line, line
    finally:
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=60)
    assert proc.returncode == 0 and "viewer stopped" in out and "Traceback" not in err, err
    # a run whose saved model no longer loads: the error names it, no server starts
    from mbctl.robots import load_robot
    from mbctl.sim import Simulator
    from mbctl.sim.trajectory import MODEL_NAME, TrajectoryRecorder

    sim = Simulator(load_robot("two_link_torque"))
    rec = TrajectoryRecorder(sim, tmp_path).attach()
    sim.step()
    rec.close()
    (tmp_path / MODEL_NAME).write_text("<mujoco><worldbody><nonsense/></worldbody></mujoco>")
    out = _mbctl("replay", str(tmp_path), "--web")
    assert out.returncode == 2 and "cannot serve this run" in out.stderr, out.stderr
    assert "Traceback" not in out.stderr and "serving" not in out.stdout


def test_a_run_whose_report_is_not_json_is_named_by_the_web_view(tmp_path):
    import pytest

    from mbctl.jobs.web_view import run_view
    from mbctl.robots import load_robot
    from mbctl.sim import Simulator
    from mbctl.sim.trajectory import TrajectoryRecorder

    sim = Simulator(load_robot("two_link_torque"))
    rec = TrajectoryRecorder(sim, tmp_path).attach()
    sim.step()
    rec.close()
    (tmp_path / "report.json").write_bytes(b"\xff{")  # the run's report damaged (its title comes from it)
    with pytest.raises(ValueError, match=r"report.json cannot be read \(.*codec"):
        run_view(tmp_path)
