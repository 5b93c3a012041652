"""A full garbage collection during the control loop against one outside it, in a large process.

    python bench/bench_loop_gc.py                     # a million objects, 3 rounds, the 2-link arm
    python bench/bench_loop_gc.py --g1                # also the G1 walk (needs MENAGERIE_ROOT)
    python bench/bench_loop_gc.py --objects 300000 --rounds 5

The process first makes ``--objects`` small containers (a list holding a dict each: what a
notebook or a test session holds). Each round times ``gc.collect()`` outside the loop, then runs the
2-link arm's PD + gravity loop (torque motors, gravity on; ``mbctl.control.run`` on the simulator,
1 s) and calls ``gc.collect()`` from its callback mid-run (what the collector does by itself when its oldest
generation's threshold trips), timed the same way. With ``--g1``, the same for ``g1-walk forward
--speed 0.3 --duration 8`` through its job (a collection at 2, 4 and 6 s of each walk; the walker
makes more objects than the arm's PD). ``control.loop.run`` freezes the objects that
exist when it starts (``gc.freeze``), so the one inside sees only what the loop made. Medians over
the rounds, the range, the ratio and the load average; the 2 ms line is the G1's period.
"""

from __future__ import annotations

import argparse
import gc
import os
import statistics
import sys
import time
from functools import partial
from pathlib import Path

import numpy as np

import mbctl.jobs.g1_walk as g1_walk
from mbctl.control import PDGravity, gains_from_frequency, joint_reference, run
from mbctl.jobs.runner import Job, run_job
from mbctl.robots import load_robot
from mbctl.sim import Simulator

#: The G1's control period [s]: a pause longer than it is a missed deadline.
G1_PERIOD_S = 0.002


def _timed_collect() -> float:
    t0 = time.perf_counter()
    gc.collect()
    return time.perf_counter() - t0


def _in_loop(robot, q_hold: np.ndarray) -> float:
    """The time [s] of a full collection called from the loop's callback, mid-run."""
    sim = Simulator(robot)
    sim.set_state(q_hold, np.zeros(robot.nv))
    inertia = np.diag(robot.mass_matrix(q_hold))
    controller = PDGravity(robot, gains_from_frequency(20.0, 1.0, inertia))
    n = round(1.0 / sim.control_period_s)
    pause = [float("nan")]

    def on_step(k, state, reference, command) -> None:
        if k == n // 2:
            pause[0] = _timed_collect()

    run(sim, controller, joint_reference(q_hold), 1.0, on_step)
    return pause[0]


def _in_walk(folder: Path) -> list[float]:
    """The times [s] of full collections called from the G1 walk job's loop at 2, 4 and 6 s."""
    pauses: list[float] = []

    def collecting_run(interface, controller, reference, duration_s, on_step=None, **options):
        at = {round(t / interface.control_period_s) for t in (2.0, 4.0, 6.0)}

        def step(k, *args):
            if k in at:
                pauses.append(_timed_collect())
            return on_step(k, *args) if on_step is not None else None

        return run(interface, controller, reference, duration_s, step, **options)

    g1_walk.run = collecting_run  # the job's loop, with the collections in its callback
    try:
        job = Job(g1_walk.G1_WALK.name, partial(g1_walk.prepare, robot=load_robot("g1")))
        record = run_job(job, g1_walk.WalkParams("forward", "0.3", 8.0), folder, quiet=True)
    finally:
        g1_walk.run = run
    if record.status != "completed":
        raise SystemExit(f"the G1 walk did not complete: {record.message}")
    return pauses


def _line(case: str, objects: int, rounds: int, outside: list[float], inside: list[float]) -> str:
    o, i = statistics.median(outside), statistics.median(inside)
    return (f"{case}: full gc.collect() with {objects} containers held, median of {rounds} rounds: outside "
            f"the loop {o * 1e3:.1f} ms (range {min(outside) * 1e3:.1f}-{max(outside) * 1e3:.1f}), inside "
            f"control.loop.run {i * 1e3:.2f} ms (range {min(inside) * 1e3:.2f}-{max(inside) * 1e3:.2f}, "
            f"{len(inside)} collections); ratio {o / i:.0f}x; inside {i / G1_PERIOD_S:.2f} of the G1's 2 ms "
            f"period, outside {o / G1_PERIOD_S:.0f} periods; load {os.getloadavg()[0]:.2f}")


def main() -> int:
    """Run the comparison."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--objects", type=int, default=1_000_000, help="containers made first")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--g1", action="store_true", help="also the G1 walk job (needs MENAGERIE_ROOT)")
    parser.add_argument("--output", type=Path, default=Path("out/bench_loop_gc"),
                        help="the walks' run folder")
    args = parser.parse_args()
    heap = [[{"i": i}] for i in range(args.objects)]  # noqa: F841 - held: the large process
    robot = load_robot("two_link_torque", gravity=True)
    q_hold = np.array([0.4, 0.8])
    outside, inside = [], []
    for _ in range(args.rounds):
        outside.append(_timed_collect())
        inside.append(_in_loop(robot, q_hold))
    print(_line("2-link PD + gravity, 1 s", args.objects, args.rounds, outside, inside))
    if args.g1:
        outside, inside = [], []
        for _ in range(args.rounds):
            outside.append(_timed_collect())
            inside += _in_walk(args.output)
        print(_line("g1-walk forward 0.3 m/s, 8 s", args.objects, args.rounds, outside, inside))
    return 0


if __name__ == "__main__":
    sys.exit(main())
