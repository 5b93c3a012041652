"""The G1 walking over DDS against ``mbctl serve g1`` (issue 28's target: < 1 % deadline misses).

Run: MENAGERIE_ROOT=../shared/menagerie python bench/bench_dds_walk.py [--seconds 20] [--runs 3] [--gait G]

Each round runs ``mbctl g1-walk forward --speed 0.3 --interface dds --watchdog-periods 50 --truth ...``
against ``mbctl serve g1 --start crouched`` (a fresh bridge and DDS domain each time, on ``lo``) twice,
interleaved: with each process on a core of its own (``mbctl --cpus 1 serve ...``, ``mbctl --cpus 0
g1-walk ...``) and without ``--cpus`` (both processes and DDS's threads on whichever core is free).
Per run: deadline misses [% of cycles] and the cycles whose CPU time alone overran the period, the
walking controller's median [us], the client's compute and IO p99 [ms], the distance and the
feet's slip from the bridge's truth log, the estimator's drift per metre walked; then median
[min, max] per mode over the rounds, with the load average at each run's start. On a machine
with one core the pinned mode is skipped.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
from pathlib import Path

import numpy as np
from bench_dds import loadavg, over_dds  # bench/ is the script's folder: on sys.path

from mbctl.unitree.domain_lock import reserve_domain

#: Per run, from the client's report.
FIGURES = ("misses_pct", "cpu_overruns_pct", "controller_us", "work_p99_ms", "distance_m", "slip_median_mm",
           "slip_max_mm", "drift_mm_per_m")
#: Each mode's ``mbctl --cpus`` for the bridge and the client (None: not pinned).
MODES: dict[str, tuple[str, str] | None] = {"pinned": ("1", "0"), "unpinned": None}


def walk_over_dds(folder: Path, seconds: float, cpus: tuple[str, str] | None,
                  gait: str = "quick") -> dict[str, float] | str:
    """One walk over DDS: its figures, or why there are none."""
    job = ["g1-walk", "forward", "--speed", "0.3", "--duration", str(seconds), "--watchdog-periods", "50",
           "--wait-s", "120", "--gait", gait]
    with reserve_domain() as domain:
        out = over_dds(domain, folder, job, "--start", "crouched", cpus=cpus)
    report = json.loads((folder / "dds" / "report.json").read_text())
    v = report["values"]
    if "cycles" not in v or v.get("fall_source") != "truth log" or v["fell"]:
        return f"exit {out.returncode}, {report['status']}: {report['message']}; fell {v.get('fell')}"
    return {"misses_pct": 100 * v["deadline_misses"] / v["cycles"],
            "cpu_overruns_pct": 100 * v["cpu_overruns"] / v["cycles"],
            "controller_us": v["controller_time_median_us"], "work_p99_ms": v["work_p99_ms"],
            "distance_m": v["distance_m"], "slip_median_mm": v["median_foot_slip_m"] * 1e3,
            "slip_max_mm": v["max_foot_slip_m"] * 1e3, "drift_mm_per_m": v["estimator_drift_m_per_m"] * 1e3}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0, help="each walk's length (s)")
    parser.add_argument("--runs", type=int, default=3, help="rounds (each: one pinned, one unpinned walk)")
    parser.add_argument("--gait", default="quick", help="g1-walk's --gait (quick, the default, or normal)")
    args = parser.parse_args()
    modes = dict(MODES) if len(os.sched_getaffinity(0)) >= 2 else {"unpinned": None}
    print(f"g1-walk forward 0.3 m/s, {args.gait} gait, {args.seconds:g} s over DDS, {args.runs} rounds of "
          f"{', '.join(modes)} "
          f"(target: misses < 1 %); load average before: {loadavg()}")
    rows: dict[str, list[dict[str, float]]] = {mode: [] for mode in modes}
    with tempfile.TemporaryDirectory() as tmp:
        for run in range(args.runs):
            for mode, cpus in modes.items():
                load = loadavg()
                got = walk_over_dds(Path(tmp) / f"{mode}-{run}", args.seconds, cpus, args.gait)
                if isinstance(got, str):
                    print(f"  {mode} run {run + 1} (load {load}): {got}")
                    continue
                rows[mode].append(got)
                figures = ", ".join(f"{k} {got[k]:.3f}" for k in FIGURES)
                print(f"  {mode} run {run + 1} (load {load}): {figures}")
    for mode, got in rows.items():
        if got:
            print(f"  {mode}: median [min, max] over {len(got)} runs")
            for key in FIGURES:
                x = np.array([r[key] for r in got])
                print(f"    {key:18s} {np.median(x):9.3f}  [{x.min():.3f}, {x.max():.3f}]")
    print(f"load average after: {loadavg()}")


if __name__ == "__main__":
    main()
