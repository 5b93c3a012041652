"""Headless video: clips of the 2-link arm and the G1 decoded and checked frame by frame."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import imageio.v3 as iio
import mujoco
import numpy as np
import pytest

from mbctl.jobs import options
from mbctl.jobs.demo import DEMO
from mbctl.jobs.g1_wbc import G1_WBC, WBCParams
from mbctl.jobs.runner import Job, Outcome, RunContext, run_job
from mbctl.robots import load_robot, torque
from mbctl.sim import Simulator
from mbctl.sim.trajectory import load_trajectory
from mbctl.sim.video import (
    VideoError,
    VideoRecorder,
    VideoSpec,
    default_camera,
    film_trajectory,
    make_renderer,
    parse_size,
)

SMALL_WH = (320, 240)
SMALL = VideoSpec(*SMALL_WH)


def _frames(path: Path) -> np.ndarray:
    return iio.imread(path).astype(float)


def test_two_link_clip_shows_the_moving_arm(tmp_path):
    sim = Simulator(load_robot("two_link_torque"))
    rec = VideoRecorder(sim, tmp_path / "arm.mp4", SMALL).attach()
    for _ in range(250):  # 0.5 s at 2 ms
        sim.step(torque([3.0, -2.0]))
    first = rec.render().astype(float)
    options = mujoco.MjvOption()
    options.geomgroup[:] = 0  # the empty scene: no geoms
    renderer = make_renderer(sim.model, *SMALL_WH)
    renderer.update_scene(sim.data, rec.camera, options)
    empty = renderer.render().astype(float)
    renderer.close()
    rec.close()
    frames = _frames(tmp_path / "arm.mp4")
    assert frames.shape == (15, 240, 320, 3)  # 0.5 s x 30 fps
    robot_pixels = (np.abs(first - empty).max(axis=-1) > 30).mean()
    assert robot_pixels > 0.01  # the robot is visible against the empty scene (>1 % of pixels)
    assert all(f.std() > 5 for f in frames)  # not blank
    assert np.abs(frames[-1] - frames[0]).mean() > 0.5  # the arm moved
    rec.close()  # idempotent


def test_g1_wbc_clip_and_replay(g1, tmp_path):
    record = run_job(G1_WBC, WBCParams("stand", 0.5), tmp_path / "run", video=SMALL)
    assert record.status == "completed" and "video" in record.files
    frames = _frames(record.files["video"])
    assert frames.shape == (15, 240, 320, 3)
    assert all(f.std() > 5 for f in frames)
    model, t, qpos, track = load_trajectory(tmp_path / "run")
    assert track == 1 and qpos.shape[1] == model.nq and t[-1] == pytest.approx(0.5)
    n = film_trajectory(model, t, qpos, tmp_path / "replay.mp4", SMALL, track)
    assert n == 16 and _frames(tmp_path / "replay.mp4").shape[0] == 16  # t = 0 .. 0.5 s inclusive


def test_the_file_on_disk_plays_to_within_a_second_of_the_last_frame(tmp_path):
    """A run killed with its encoder (power loss, OOM, kill -9 of the group) keeps what was written.

    3 s of the arm are filmed and the recorder is never closed: the file on disk must decode to
    at least 2 s (x264's defaults wrote nothing playable before closing). The wait is bounded
    and ends as soon as ffmpeg has caught up with the frames it was sent.
    """
    sim = Simulator(load_robot("two_link_torque"))
    rec = VideoRecorder(sim, tmp_path / "live.mp4", SMALL).attach()
    for _ in range(1500):  # 3 s at 2 ms: 90 frames sent
        sim.step(torque([1.0, -0.5]))
    assert rec.frames == 90
    on_disk = tmp_path / "live.mp4"  # written at its name from the first frame
    snapshot, readable, deadline = tmp_path / "snapshot.mp4", 0, time.monotonic() + 60.0
    while readable < 60 and time.monotonic() < deadline:
        shutil.copyfile(on_disk, snapshot)  # what a reader finds on disk now
        try:
            readable = iio.imread(snapshot).shape[0]
        except OSError:  # no complete fragment yet
            readable = 0
        time.sleep(0.1)
    assert readable >= 60  # measured 72 (0.6 s behind); before the fix nothing decoded
    rec.close()
    assert _frames(tmp_path / "live.mp4").shape[0] == 90


def test_two_link_video_light_background_arm_large(tmp_path):
    record = run_job(DEMO, options.demo(duration=0.5), tmp_path, video=SMALL)
    frames = _frames(record.files["video"])
    corners = np.concatenate([frames[:, :8, :8], frames[:, -8:, -8:]], axis=1)
    assert corners.mean() > 200  # a light backdrop (MuJoCo's default is black)
    dark = (frames.max(axis=-1) < 150)  # the arm's links (dark blue, brown) against it
    rows, cols = np.nonzero(dark.any(axis=0))
    assert np.ptp(rows) > 0.4 * frames.shape[1] and np.ptp(cols) > 0.4 * frames.shape[2]  # large


def _interrupted(params: None):
    def work(ctx: RunContext) -> Outcome:
        sim = ctx.attach(Simulator(load_robot("two_link_torque")))
        for _ in range(150):  # 0.3 s
            sim.step(torque([1.0, 0.0]))
        raise KeyboardInterrupt

    return work


def test_interrupted_run_leaves_a_playable_video(tmp_path):
    record = run_job(Job("clip", _interrupted), None, tmp_path, video=SMALL)
    assert record.status == "interrupted" and record.exit_code == 130
    assert _frames(tmp_path / "video.mp4").shape[0] == 9  # 0.3 s x 30 fps
    assert load_trajectory(tmp_path)[2].shape == (151, 2)


#: The run killed with SIGKILL: 1.5 s of the arm filmed (45 frames), then it waits to be killed.
_KILLED_RUN = textwrap.dedent("""
    import sys, time
    from mbctl.jobs.runner import Job, Outcome, run_job
    from mbctl.robots import load_robot, torque
    from mbctl.sim import Simulator
    from mbctl.sim.video import VideoSpec

    def prepare(params):
        def work(ctx):
            sim = ctx.attach(Simulator(load_robot("two_link_torque")))
            for _ in range(750):
                sim.step(torque([1.0, -0.5]))
            print("filmed", flush=True)
            time.sleep(600)
            return Outcome(True, (), "")
        return work

    run_job(Job("clip", prepare), None, sys.argv[1], video=VideoSpec(320, 240))
""")


def _writers_of(path: Path) -> list[int]:
    """Pids of the processes whose stdout is ``path`` (the encoder of a killed run)."""
    pids = []
    for proc in Path("/proc").iterdir():
        try:
            if proc.name.isdigit() and os.readlink(proc / "fd" / "1") == str(path):
                pids.append(int(proc.name))
        except OSError:
            continue
    return pids


def test_a_run_killed_with_sigkill_leaves_its_video_at_its_name(tmp_path):
    """SIGKILL mid-run: the video was ``.video.mp4.*.tmp`` (hidden, and removed by the next run);
    now it is ``video.mp4``, and the encoder, which outlives the run, finishes it: all 45 frames."""
    run = tmp_path / "run"
    child = subprocess.Popen([sys.executable, "-c", _KILLED_RUN, str(run)], stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout is not None and child.stdout.readline() == "filmed\n"
        encoders = _writers_of(run / "video.mp4")
        assert len(encoders) == 1  # ffmpeg writes the video at its name while the run goes on
        child.send_signal(signal.SIGKILL)
    finally:
        child.kill()
        child.wait()
    assert child.returncode == -signal.SIGKILL
    for pid in encoders:  # the encoder reads the end of its input and closes the file
        for _ in range(600):
            if pid not in _writers_of(run / "video.mp4"):
                break
            time.sleep(0.1)
    assert not _writers_of(run / "video.mp4")
    names = sorted(p.name for p in run.iterdir())
    assert "video.mp4" in names and not [n for n in names if "mp4" in n and n != "video.mp4"], names
    assert _frames(run / "video.mp4").shape == (45, 240, 320, 3)


@pytest.mark.parametrize("text", ["640", "640x", "x480", "640x481", "8x8", "abcxdef"])
def test_bad_sizes_are_named(text):
    with pytest.raises(VideoError, match="video"):
        VideoSpec(*parse_size(text))


def test_frames_drawn_by_several_workers_arrive_in_order(tmp_path):
    """Frame k of a replay drawn by 3 worker processes is frame k drawn by one (none swapped)."""
    robot = load_robot("two_link_torque")
    t = np.linspace(0.0, 1.0, 101)
    qpos = np.stack([np.linspace(0.0, 3.0, 101), np.linspace(0.0, -1.5, 101)], axis=1)
    model = robot.mj_model
    assert film_trajectory(model, t, qpos, tmp_path / "one.mp4", SMALL, workers=1) == 31
    assert film_trajectory(model, t, qpos, tmp_path / "three.mp4", SMALL, workers=3) == 31
    one, three = _frames(tmp_path / "one.mp4"), _frames(tmp_path / "three.mp4")
    assert one.shape == three.shape == (31, 240, 320, 3)
    a, b = three[:, ::4, ::4], one[:, ::4, ::4]
    diff = np.abs(a[:, None] - b[None]).mean(axis=(2, 3, 4))  # (31, 31) frame against frame
    assert list(diff.argmin(axis=1)) == list(range(31))
    steps = np.abs(np.diff(b, axis=0)).mean(axis=(1, 2, 3))  # from one frame to the next
    assert diff.diagonal().max() < 1.0 < np.median(steps)


def test_software_gl_draws_without_multisampling_and_shadows():
    from mbctl.sim.video_workers import fast_renderer, is_software_gl

    assert is_software_gl("llvmpipe (LLVM 15.0.6, 256 bits)") and is_software_gl("Mesa OffScreen softpipe")
    assert is_software_gl("")  # unknown: the cheap settings
    assert not is_software_gl("NVIDIA GeForce RTX 3060/PCIe/SSE2")
    model = load_robot("two_link_torque").mj_model
    model.vis.quality.offsamples = 4
    renderer = fast_renderer(model, 64, 48, software=True)
    assert model.vis.quality.offsamples == 0
    assert not renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW]
    assert not renderer.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION]
    assert not renderer.scene.flags[mujoco.mjtRndFlag.mjRND_HAZE]
    renderer.close()
    model.vis.quality.offsamples = 4
    renderer = fast_renderer(model, 64, 48, software=False)
    assert model.vis.quality.offsamples == 4 and renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW]
    assert renderer.scene.flags[mujoco.mjtRndFlag.mjRND_HAZE]
    renderer.close()


def test_a_video_into_a_directory_is_refused_naming_it(tmp_path):
    sim = Simulator(load_robot("two_link_torque"))
    with pytest.raises(VideoError, match=f"{tmp_path} is a directory; give a file name for the video"):
        VideoRecorder(sim, tmp_path, SMALL)


def test_ctrl_c_at_the_terminal_keeps_every_frame(tmp_path):
    """SIGINT to the run's whole process group (a Ctrl-C at a terminal): the render workers, in
    their own session, are not interrupted; the run stops and its video has all 45 frames."""
    run = tmp_path / "run"
    child = subprocess.Popen([sys.executable, "-c", _KILLED_RUN, str(run)], stdout=subprocess.PIPE, text=True,
                             start_new_session=True)
    try:
        assert child.stdout is not None and child.stdout.readline() == "filmed\n"
        os.killpg(child.pid, signal.SIGINT)
        child.wait(timeout=300)
    finally:
        child.kill()
        child.wait()
    assert '"status": "interrupted"' in (run / "report.json").read_text()
    assert _frames(run / "video.mp4").shape == (45, 240, 320, 3)


def test_the_workers_mp4_mode_is_the_runs_file_mode():
    from mbctl.sim import atomic, video_workers

    assert video_workers.FILE_MODE == atomic.FILE_MODE == 0o644


def test_meshes_merged_below_a_pixel_draw_the_same_g1_frame(g1):
    """Software GL: the G1's vertices closer than a pixel at the camera's distance merged (its
    393270 triangles to about a quarter); the frame is the full-mesh frame to within 1 of 255."""
    import copy

    from mbctl.sim.video_pool import pixel_size_m
    from mbctl.sim.video_workers import CameraSpec, fast_renderer, simplify_meshes

    sim = Simulator(g1)
    sim.step(n=50)
    camera = default_camera(sim.model, sim.data, 1)
    cell = pixel_size_m(sim.model, CameraSpec.of(camera), 480)
    assert 0.002 < cell < 0.01  # a pixel of the tracking camera's 640x480 frame [m]
    frames = []
    model = copy.deepcopy(sim.model)
    for simplify in (False, True):
        if simplify:
            before, after = simplify_meshes(model, cell)
            assert before == 393270 and 0.15 * before < after < 0.4 * before
        renderer = fast_renderer(model, 640, 480, software=True)
        renderer.update_scene(sim.data, camera)
        frames.append(renderer.render().astype(float))
        renderer.close()
    diff = np.abs(frames[1] - frames[0])
    assert diff.mean() < 1.0 and (diff.max(axis=-1) > 30).mean() < 0.01


def test_render_workers_and_their_encoder_run_below_the_simulation(tmp_path):
    """Every render worker (and the ffmpeg it starts) runs WORKER_NICE below the filming process."""
    from mbctl.sim.video_pool import RenderPool
    from mbctl.sim.video_workers import WORKER_NICE, CameraSpec, FrameState

    def nice(pid: int) -> int:  # field 19 of /proc/PID/stat, after the command's parentheses
        return int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[16])

    model = load_robot("two_link_torque").mj_model
    camera = CameraSpec.of(default_camera(model, mujoco.MjData(model), 0))
    pool = RenderPool(model, *SMALL_WH, camera, tmp_path / "clip.mp4", 30.0, workers=2)
    try:
        pool.submit(FrameState(np.zeros(model.nq), np.zeros((0, 3)), np.zeros((0, 4)), None))
        ours = os.getpriority(os.PRIO_PROCESS, 0)
        workers = [proc.pid for proc in pool._procs]
        assert [nice(pid) for pid in workers] == [min(19, ours + WORKER_NICE)] * 2
        encoders = subprocess.run(["ps", "-o", "pid=,ni=", "--ppid", str(workers[0])], capture_output=True,
                                  text=True, check=True).stdout.split()
        assert encoders[1::2] == [str(min(19, ours + WORKER_NICE))]
    finally:
        pool.close()
    assert _frames(tmp_path / "clip.mp4").shape == (1, 240, 320, 3)
