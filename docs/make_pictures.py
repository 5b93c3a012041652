"""Make the pictures of the README and the DDS guide: a G1 still, the demo's plot, the g1-wbc latency sweep.

    MENAGERIE_ROOT=... python docs/make_pictures.py

Runs headless (EGL, then OSMesa). The G1 still needs the Menagerie model; the demo runs anywhere.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

from mbctl.gl import choose_gl_backend

choose_gl_backend()  # before mujoco is imported

import mujoco  # noqa: E402
from matplotlib import image  # noqa: E402

from mbctl.jobs.demo import DEMO, DemoConfig  # noqa: E402
from mbctl.jobs.runner import run_job  # noqa: E402
from mbctl.jobs.sweep import SweepConfig, run_sweep  # noqa: E402
from mbctl.robots import load_robot  # noqa: E402
from mbctl.sim.trajectory import base_body  # noqa: E402
from mbctl.sim.video import VideoSpec, still  # noqa: E402

DOCS = Path(__file__).resolve().parent


def g1_still(path: Path) -> None:
    """The G1 at its ``stand`` keyframe, 480x360."""
    robot = load_robot("g1")
    data = mujoco.MjData(robot.mj_model)
    mujoco.mj_resetDataKeyframe(robot.mj_model, data, robot.keyframe_id("stand"))
    image.imsave(path, still(robot.mj_model, data, VideoSpec(480, 360), base_body(robot)))


def demo_plot(path: Path) -> None:
    """The demo's plot (computed torque on the 0.2 m square)."""
    with tempfile.TemporaryDirectory() as tmp:
        record = run_job(DEMO, DemoConfig(), Path(tmp))
        shutil.copyfile(record.files["plot"], path)


def latency_sweep(path: Path) -> None:
    """Whether g1-wbc stand and squat fall with 0-45 ms of link latency each way (in-process, Dask)."""
    with tempfile.TemporaryDirectory() as tmp:
        latencies_ms: list[object] = [float(x) for x in range(0, 50, 5)]
        grid: dict[str, list[object]] = {"scenario": ["squat", "stand"], "latency_ms": latencies_ms}
        result = run_sweep(SweepConfig("g1-wbc", grid, Path(tmp) / "sweep", metric="fell"))
        shutil.copyfile(result.files["plot"], path)


if __name__ == "__main__":
    g1_still(DOCS / "g1_stand.png")
    demo_plot(DOCS / "demo.png")
    latency_sweep(DOCS / "g1_wbc_latency.png")
    print(f"wrote {DOCS / 'g1_stand.png'}, {DOCS / 'demo.png'}, {DOCS / 'g1_wbc_latency.png'}")
