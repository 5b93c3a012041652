"""Cost of filming: render + encode per frame, and the slowdown of a job run with --video.

    MENAGERIE_ROOT=... python bench/bench_video.py

Prints medians measured in this run: per-frame cost at 640x480 for the 2-link arm and the G1,
and g1-stand (2 s) / demo wall time with and without --video, interleaved, with their ratios.
"""

from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path

from mbctl.gl import choose_gl_backend

BACKEND = choose_gl_backend()  # before mujoco is imported

from bench.harness import interleaved  # noqa: E402
from mbctl.jobs.demo import DEMO, DemoConfig  # noqa: E402
from mbctl.jobs.g1 import G1_STAND, StandParams  # noqa: E402
from mbctl.jobs.runner import run_job  # noqa: E402
from mbctl.robots import load_robot  # noqa: E402
from mbctl.sim import Simulator  # noqa: E402
from mbctl.sim.video import VideoRecorder, VideoSpec  # noqa: E402


def per_frame_ms(robot_name: str, n: int = 60) -> tuple[float, float]:
    """(render, render + encode) median ms per 640x480 frame."""
    sim = Simulator(load_robot(robot_name))
    with tempfile.TemporaryDirectory() as tmp:
        rec = VideoRecorder(sim, Path(tmp) / "v.mp4", VideoSpec())
        render, total = [], []
        for _ in range(n):
            sim.step(n=17)
            t0 = time.perf_counter()
            frame = rec.render()
            t1 = time.perf_counter()
            rec._writer.append_data(frame)
            t2 = time.perf_counter()
            render.append(t1 - t0)
            total.append(t2 - t0)
        rec.close()
    return 1e3 * statistics.median(render), 1e3 * statistics.median(total)


def job_times() -> dict[str, float]:
    tmp = Path(tempfile.mkdtemp())

    def job(j, params, video):  # noqa: ANN001, ANN202
        return lambda: run_job(j, params, tmp / f"{j.name}-{video}", video=VideoSpec() if video else None)

    return interleaved({
        "demo": job(DEMO, DemoConfig(), False),
        "demo --video": job(DEMO, DemoConfig(), True),
        "g1-stand 2 s": job(G1_STAND, StandParams(2.0), False),
        "g1-stand 2 s --video": job(G1_STAND, StandParams(2.0), True),
    }, repeats=3)


def main() -> None:
    print(f"OpenGL backend: {BACKEND}")
    for name in ("two_link_torque", "g1"):
        render, total = per_frame_ms(name)
        print(f"{name:16s} per 640x480 frame: render {render:6.2f} ms, "
              f"render + encode {total:6.2f} ms (median)")
    times = job_times()
    for key in ("demo", "g1-stand 2 s"):
        off, on = times[key], times[f"{key} --video"]
        print(f"{key:14s} wall time: {off:6.2f} s without video, {on:6.2f} s with --video: x{on / off:.2f}")


if __name__ == "__main__":
    main()
