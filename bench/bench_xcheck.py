"""Cross-check throughput on the G1: states per second with every quantity, on one core.

Run: MENAGERIE_ROOT=../shared/menagerie python bench/bench_xcheck.py [--states N] [--runs R]
Prints the median over R runs of (a) the evaluation alone (both engines, conversions, error
reduction: ``Report.states_per_second``) and (b) the whole ``crosscheck`` call (also sampling,
the private model copy and the load-time agreement check). Goal: >= 2,000 states/s.
"""

from __future__ import annotations

import os

# One core: no BLAS threads, and the process pinned to one CPU where the OS allows it.
for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import argparse  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402

from mbctl.robots import load_robot  # noqa: E402
from mbctl.robots.crosscheck import crosscheck  # noqa: E402

GOAL_STATES_PER_S = 2000.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="g1")
    parser.add_argument("--states", type=int, default=2000, help="random states per run")
    parser.add_argument("--runs", type=int, default=7)
    args = parser.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    robot = load_robot(args.robot)
    crosscheck(robot, n_states=50, seed=0)  # warm-up
    eval_rates, total_rates = [], []
    for run in range(args.runs):
        t0 = time.perf_counter()
        report = crosscheck(robot, n_states=args.states, seed=run)
        total = time.perf_counter() - t0
        if not report.passed:
            raise SystemExit(f"cross-check failed on run {run}:\n{report.to_text()}")
        eval_rates.append(report.states_per_second)
        total_rates.append(report.n_states / total)
    worst = max(q.max_rel_error for q in report.quantities)
    print(
        f"robot {args.robot}: nq={robot.nq} nv={robot.nv}, "
        f"{len(robot.bodies)} bodies, {len(robot.sites)} sites"
    )
    print(
        f"{args.runs} runs x {report.n_states} states, all {len(report.quantities) - 1} quantities, one core"
    )
    print(
        f"evaluation : median {statistics.median(eval_rates):8.0f} states/s "
        f"(min {min(eval_rates):.0f}, max {max(eval_rates):.0f})"
    )
    print(
        f"end to end : median {statistics.median(total_rates):8.0f} states/s "
        f"(min {min(total_rates):.0f}, max {max(total_rates):.0f})"
    )
    print(f"largest relative error in the last run: {worst:.2e}")
    verdict = "met" if statistics.median(eval_rates) >= GOAL_STATES_PER_S else "NOT met"
    print(f"goal {GOAL_STATES_PER_S:.0f} states/s (evaluation): {verdict}")


if __name__ == "__main__":
    main()
