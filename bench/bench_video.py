"""Cost of filming (issue 30): where a frame's time goes, and a job and a replay with --video.

    MENAGERIE_ROOT=... python -m bench.bench_video [--runs 3] [--duration S] [--section frame|job|all]

``frame``: per 640x480 frame of the G1 (and the 2-link arm), in this process: ``update_scene``,
``render`` with MuJoCo's defaults (4x multisampling, shadows, haze), without them, and with the
video's settings on software GL (none, and the meshes merged below a pixel), the encoder
(the pipe write here, ffmpeg's own CPU from its rusage), and what the job's process pays per
frame with render workers (the frame's state and its send).
CPU time of the process (llvmpipe's threads included) and wall time, medians of 20 frames.

``job``: ``mbctl g1-wbc squat`` with and without ``--video`` (default size and rate), as
subprocesses, alternated, ``--runs`` times: median and range of each wall time and of the
same-run ratio; then ``mbctl replay RUN --video`` against the run's simulated time. The load
average is printed with each figure: the machine may be shared.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from mbctl.gl import choose_gl_backend

BACKEND = choose_gl_backend()  # before mujoco is imported

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from mbctl.robots import load_robot  # noqa: E402
from mbctl.sim import Simulator  # noqa: E402
from mbctl.sim.trajectory import base_body  # noqa: E402
from mbctl.sim.video import VideoRecorder, VideoSpec, default_camera  # noqa: E402
from mbctl.sim.video_pool import pixel_size_m  # noqa: E402
from mbctl.sim.video_workers import (  # noqa: E402
    CameraSpec,
    Writer,
    fast_renderer,
    gl_renderer_name,
    is_software_gl,
    simplify_meshes,
)

MBCTL = [sys.executable, "-m", "mbctl.cli"]


def load() -> str:
    """The 1-minute load average, for the figure printed next to it."""
    return f"load {os.getloadavg()[0]:.2f}"


def _span(values: list[float], fmt: str = "{:.2f}") -> str:
    """Median and range of ``values``."""
    return f"{fmt.format(statistics.median(values))} ({fmt.format(min(values))}-{fmt.format(max(values))})"


def _timed(fn, n: int) -> tuple[float, float]:  # noqa: ANN001
    """Median (CPU, wall) [ms] of ``n`` calls of ``fn``."""
    cpu, wall = [], []
    fn()
    for _ in range(n):
        c0, w0 = time.process_time(), time.perf_counter()
        fn()
        cpu.append(time.process_time() - c0)
        wall.append(time.perf_counter() - w0)
    return 1e3 * statistics.median(cpu), 1e3 * statistics.median(wall)


def frame_costs(robot_name: str, n: int = 20) -> None:
    """Print where one 640x480 frame's time goes (see the module doc)."""
    spec = VideoSpec()
    sim = Simulator(load_robot(robot_name))
    sim.step(n=100)
    model, data = sim.model, sim.data
    camera = default_camera(model, data, base_body(sim.robot))
    options = mujoco.MjvOption()
    options.flags[mujoco.mjtVisFlag.mjVIS_CONTACTFORCE] = True
    rows = []
    samples = int(model.vis.quality.offsamples)
    cell = pixel_size_m(model, CameraSpec.of(camera), spec.height)
    for label, software, simplify in (("MuJoCo's defaults (4x MSAA, shadows)", False, False),
                                      ("no MSAA, shadows, haze", True, False),
                                      ("+ meshes merged below a pixel (the video)", True, True)):
        model.vis.quality.offsamples = samples
        if simplify:
            faces = simplify_meshes(model, cell)
        renderer = fast_renderer(model, spec.width, spec.height, software)
        if not software:
            renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = True
        update = _timed(lambda r=renderer: r.update_scene(data, camera, options), n)
        render = _timed(renderer.render, n)
        rows.append((label, update, render))
        frame = renderer.render()
        renderer.close()
    model.vis.quality.offsamples = samples
    with tempfile.TemporaryDirectory() as tmp:
        writer = Writer(Path(tmp) / "v.mp4", spec.fps)
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        write = _timed(lambda: writer.append_data(frame), n)
        writer.close()
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        ffmpeg_ms = 1e3 * ((after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)) / (n + 1)
        sim = Simulator(load_robot(robot_name))  # its model unmerged
        sim.step(n=100)
        rec = VideoRecorder(sim, Path(tmp) / "w.mp4", VideoSpec(contact_forces=True), workers=1)
        state = _timed(rec.frame_state, n)
        rec.close()
    print(f"{robot_name}, one {spec.width}x{spec.height} frame, CPU ms (wall ms), median of {n}, {load()}; "
          f"mesh triangles {faces[0]} -> {faces[1]} merged at {1e3 * cell:.1f} mm:")
    for label, update, render in rows:
        print(f"  {label:44s} update_scene {update[0]:5.3f} ({update[1]:5.3f})  "
              f"render {render[0]:7.1f} ({render[1]:7.1f})")
    print(f"  encoder: pipe write {write[0]:.2f} ({write[1]:.2f}), "
          f"ffmpeg (libx264) {ffmpeg_ms:.1f} CPU per frame")
    print(f"  the job's process per frame with render workers (pose + contact arrows): {state[0]:.3f} "
          f"({state[1]:.3f})")


def _cpu_children() -> float:
    """CPU time [s] of this process's waited-for descendants (workers and ffmpeg included)."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _run(args: list[str], cwd: Path) -> tuple[float, float]:
    """(wall, CPU) time [s] of ``mbctl args`` (exit 0 required), CPU summed over its processes."""
    c0, t0 = _cpu_children(), time.perf_counter()
    out = subprocess.run(MBCTL + args, cwd=cwd, capture_output=True, text=True)
    wall, cpu = time.perf_counter() - t0, _cpu_children() - c0
    if out.returncode != 0:
        raise SystemExit(f"mbctl {' '.join(args)} exited {out.returncode}: {out.stderr[-800:]}")
    return wall, cpu


def job_ratio(runs: int, duration: float | None) -> None:
    """Print g1-wbc squat with and without --video, and replay --video, over ``runs`` runs."""
    extra = ["--duration", str(duration)] if duration is not None else []
    simulated = duration if duration is not None else 10.0
    tmp = Path(tempfile.mkdtemp(prefix="bench_video_"))
    plain, filmed, ratios, replays, loads = [], [], [], [], []
    cpu: dict[str, list[float]] = {"plain": [], "filmed": [], "replay": []}
    for k in range(runs):
        loads.append(os.getloadavg()[0])
        wall, c = _run(["g1-wbc", "squat", *extra, "--output", str(tmp / f"plain{k}"), "--quiet"], tmp)
        plain.append(wall)
        cpu["plain"].append(c)
        wall, c = _run(["g1-wbc", "squat", *extra, "--output", str(tmp / f"video{k}"), "--quiet", "--video"],
                       tmp)
        filmed.append(wall)
        cpu["filmed"].append(c)
        ratios.append(filmed[-1] / plain[-1])
        wall, c = _run(["replay", str(tmp / f"video{k}"), "--video", "--output", str(tmp / f"r{k}.mp4")], tmp)
        replays.append(wall)
        cpu["replay"].append(c)
        loads.append(os.getloadavg()[0])
        print(f"  run {k + 1}: squat {plain[-1]:.1f} s (CPU {cpu['plain'][-1]:.1f}), "
              f"--video {filmed[-1]:.1f} s (CPU {cpu['filmed'][-1]:.1f}; x{ratios[-1]:.2f}), "
              f"replay --video {replays[-1]:.1f} s (CPU {cpu['replay'][-1]:.1f}); "
              f"load {loads[-2]:.2f} -> {loads[-1]:.2f}", flush=True)
    frames = len(np.load(tmp / "video0" / "trajectory.npz")["time_s"])
    print(f"g1-wbc squat ({simulated:g} s simulated, {frames} trajectory samples), {runs} runs, "
          f"load {min(loads):.2f}-{max(loads):.2f}, median (range):")
    print(f"  without video {_span(plain, '{:.1f}')} s; with --video {_span(filmed, '{:.1f}')} s; "
          f"same-run ratio x{_span(ratios)} (goal <= 2)")
    print(f"  replay --video {_span(replays, '{:.1f}')} s = x{_span([r / simulated for r in replays])} "
          f"the simulated time (goal <= 1)")
    print(f"  CPU time summed over the processes: squat {_span(cpu['plain'], '{:.1f}')} s, --video "
          f"{_span(cpu['filmed'], '{:.1f}')} s, replay --video {_span(cpu['replay'], '{:.1f}')} s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--duration", type=float, default=None, help="squat duration [s] (default: its 10 s)")
    parser.add_argument("--section", choices=("frame", "job", "all"), default="all")
    args = parser.parse_args()
    name = gl_renderer_name()
    kind = "software" if is_software_gl(name) else "GPU"
    print(f"OpenGL: MUJOCO_GL={BACKEND}, {name or 'unknown'} ({kind}); "
          f"{len(os.sched_getaffinity(0))} cores; {load()}")
    if args.section in ("frame", "all"):
        frame_costs("g1")
        frame_costs("two_link_torque")
    if args.section in ("job", "all"):
        job_ratio(args.runs, args.duration)


if __name__ == "__main__":
    main()
