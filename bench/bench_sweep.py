"""mbctl sweep on Dask: speed-up of 2 workers over 1, per-task overhead, open-loop rollouts.

1. 16 tasks of ``g1-stand --duration 2`` through ``run_sweep`` on a LocalCluster of 1 worker and
   of 2 workers (one thread each; robots loaded on every worker before the clock starts), the
   sweeps alternated: median wall times and the speed-up, beside 16 x the direct call.
2. Per-task overhead: one task at a time through Dask (submit, run, result) against
   ``run_task`` called directly, medians of the same task.
3. Open-loop batches (no controller in the loop): N rollouts of the G1 holding its stand
   keyframe's ctrl, via ``mujoco.rollout.rollout`` with 1 and 2 threads, and via Dask tasks (one
   rollout per task).

Run: ``MENAGERIE_ROOT=... PYTHONPATH=... python bench/bench_sweep.py [--tasks 16] [--rollouts 32]``.
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import statistics
import tempfile
import time
from pathlib import Path

import mujoco
import numpy as np
from dask.distributed import Client, LocalCluster
from mujoco import rollout

from mbctl.jobs.catalog import RobotSource, parse_grid
from mbctl.jobs.sweep import SweepConfig, cached_robot, run_sweep, run_task
from mbctl.jobs.sweep_cluster import local_cluster

JOB, DURATION = "g1-stand", 2.0
ROLLOUT_STEPS = 1000  # 2 s at the G1's 2 ms step


def cluster(workers: int) -> tuple[LocalCluster, Client]:
    c = local_cluster(workers)  # as mbctl sweep starts it
    client = Client(c)
    client.run(preload)  # every worker loads the G1 before the clock starts
    return c, client


def preload() -> None:
    """Load the G1 into this process's robot cache and the rollout setup (returns nothing to send)."""
    cached_robot(RobotSource("g1"))
    g1_rollout_setup()


def work_times(folder: Path) -> list[float]:
    """Each run's own wall time [s] (``report.json``: the job's work, without prepare and Dask)."""
    return [json.loads(f.read_text())["wall_time_s"] for f in folder.glob("runs/*/report.json")]


def sweep_wall(client: Client, tasks: int, out: Path) -> float:
    zetas = ",".join(f"{1 + i / 100:g}" for i in range(tasks))  # 16 distinct runs of the same cost
    grid = parse_grid(JOB, [f"duration={DURATION}", f"zeta={zetas}"])
    result = run_sweep(SweepConfig(JOB, grid, out), client=client)
    assert len(result.rows) == tasks and not result.failures, result.failures
    return result.wall_time_s


@functools.lru_cache(maxsize=1)
def g1_rollout_setup() -> tuple[mujoco.MjModel, np.ndarray, np.ndarray]:
    """The G1 plant, N initial states (stand keyframe, pelvis height jittered) and held ctrl."""
    robot = cached_robot(RobotSource("g1"))
    model = robot.mj_model
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("stand").id)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, state, spec)
    return model, state, data.ctrl.copy()


def one_rollout(index: int) -> float:
    """One open-loop G1 rollout (1 thread); returns the final pelvis height [m]."""
    model, state, ctrl = g1_rollout_setup()
    x0 = state.copy()
    x0[1 + 2] += 1e-3 * index  # qpos[2]: pelvis height (state = time, qpos, ...)
    states, _ = rollout.rollout(model, mujoco.MjData(model), x0[None], np.tile(ctrl, (1, ROLLOUT_STEPS, 1)))
    return float(states[0, -1, 3])


def batch_rollout(n: int, threads: int) -> np.ndarray:
    model, state, ctrl = g1_rollout_setup()
    x0 = np.tile(state, (n, 1))
    x0[:, 3] += 1e-3 * np.arange(n)
    datas = [mujoco.MjData(model) for _ in range(threads)]
    states, _ = rollout.rollout(model, datas, x0, np.tile(ctrl, (n, ROLLOUT_STEPS, 1)))
    return states[:, -1, 3]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tasks", type=int, default=16)
    ap.add_argument("--rollouts", type=int, default=32)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--sweeps", type=int, default=3)
    args = ap.parse_args()
    out = Path(tempfile.mkdtemp(prefix="bench_sweep_"))
    load_before = os.getloadavg()[0]
    cached_robot(RobotSource("g1"))

    clusters = {workers: cluster(workers) for workers in (1, 2)}
    walls: dict[int, list[float]] = {1: [], 2: []}
    try:
        for r in range(args.sweeps):  # alternated, so machine noise hits both alike
            for workers, (_, client) in clusters.items():
                walls[workers].append(sweep_wall(client, args.tasks, out / f"sweep{workers}-{r}"))
        client = clusters[1][1]
        values = {"duration": DURATION}
        dask_s, call_s = [], []
        for i in range(args.repeats):  # interleaved, the same task
            t = time.perf_counter()
            client.submit(run_task, JOB, values, str(out / "oh_dask" / str(i)), pure=False).result()
            dask_s.append(time.perf_counter() - t)
            t = time.perf_counter()
            run_task(JOB, values, str(out / "oh_direct" / str(i)))
            call_s.append(time.perf_counter() - t)
        empty = []
        for _ in range(20):  # Dask's own round trip: an empty task
            t = time.perf_counter()
            client.submit(_nothing, pure=False).result()
            empty.append(time.perf_counter() - t)
        overhead = {"dask": statistics.median(dask_s), "direct": statistics.median(call_s),
                    "empty": statistics.median(empty)}
        client = clusters[2][1]
        one_rollout(0)
        t = time.perf_counter()
        client.gather(client.map(one_rollout, range(args.rollouts), pure=False))
        dask_rollouts = time.perf_counter() - t
    finally:
        for c, client in clusters.values():
            client.close()
            c.close()
    w1, w2 = statistics.median(walls[1]), statistics.median(walls[2])
    work = {w: statistics.median(t for r in range(args.sweeps) for t in work_times(out / f"sweep{w}-{r}"))
            for w in (1, 2)}
    direct_serial = args.tasks * overhead["direct"]

    print(f"1. {args.tasks} x {JOB} --duration {DURATION:g} (wall, robot preloaded, median of "
          f"{args.sweeps} sweeps each, alternated):")
    print(f"   direct, serial ({args.tasks} x the direct median below): {direct_serial:7.2f} s")
    print(f"   Dask, 1 worker:  {w1:7.2f} s  (all: {', '.join(f'{w:.2f}' for w in walls[1])})")
    print(f"   Dask, 2 workers: {w2:7.2f} s  (all: {', '.join(f'{w:.2f}' for w in walls[2])})")
    print(f"   speed-up 2 workers / 1 worker: {w1 / w2:.2f}x (target >= 1.8x); "
          f"2 workers / direct serial: {direct_serial / w2:.2f}x")
    print(f"   one run's own work (report wall_time_s, median): 1 worker {work[1] * 1e3:.0f} ms, 2 workers "
          f"{work[2] * 1e3:.0f} ms ({work[2] / work[1]:.2f}x: above 1 means the 2 workers shared the cores "
          "with something else)")
    print(f"2. per task ({JOB} --duration {DURATION:g}, median of {args.repeats}): direct "
          f"{overhead['direct'] * 1e3:.0f} ms, through Dask {overhead['dask'] * 1e3:.0f} ms; overhead "
          f"{(overhead['dask'] - overhead['direct']) * 1e3:.0f} ms "
          f"({overhead['dask'] / overhead['direct']:.3f}x); an empty task's round trip "
          f"{overhead['empty'] * 1e3:.1f} ms (median of 20)")
    t1 = statistics.median(_timed(lambda: batch_rollout(args.rollouts, 1)) for _ in range(args.repeats))
    t2 = statistics.median(_timed(lambda: batch_rollout(args.rollouts, 2)) for _ in range(args.repeats))
    steps = args.rollouts * ROLLOUT_STEPS
    print(f"3. {args.rollouts} open-loop G1 rollouts x {ROLLOUT_STEPS} steps (median of {args.repeats}):")
    print(f"   mujoco.rollout 1 thread:  {t1:6.2f} s ({steps / t1:,.0f} steps/s)")
    print(f"   mujoco.rollout 2 threads: {t2:6.2f} s ({steps / t2:,.0f} steps/s), {t1 / t2:.2f}x")
    print(f"   Dask, 2 workers, 1 rollout per task: {dask_rollouts:6.2f} s, "
          f"{dask_rollouts / t2:.2f}x the 2-thread rollout")
    print(f"load average (1 min) before {load_before:.2f}, after {os.getloadavg()[0]:.2f} on "
          f"{os.cpu_count()} cores; run folders in {out}")


def _nothing() -> None:
    """An empty task."""


def _timed(fn: object) -> float:
    t = time.perf_counter()
    fn()  # type: ignore[operator]
    return time.perf_counter() - t


if __name__ == "__main__":
    main()
