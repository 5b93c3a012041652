"""Start-up time of the command line: ``mbctl --help`` against ``python -c "import mujoco, pinocchio"``.

Run: python bench/bench_cli.py [--rounds 15] [--module]

``--module`` runs ``python -m mbctl.cli`` instead of the ``mbctl`` console script, e.g. to time
another source tree of the package put first on ``PYTHONPATH``.

Each command runs as a fresh subprocess (what a user waits for), rounds interleaved so machine
noise hits all alike; medians, and the range of the per-round ratios. ``mbctl demo --help`` (one
command's help) is timed beside them. The reference is the bare import of the two engines any
toolkit on them pays once; the help needs neither.

Goal (issue 21): help/import <= 1.5x.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

GOAL = 1.5


def _mbctl(module: bool) -> list[str]:
    if module:
        return [sys.executable, "-m", "mbctl.cli"]
    script = Path(sys.executable).parent / "mbctl"
    found = str(script) if script.exists() else shutil.which("mbctl")
    return [found] if found else [sys.executable, "-m", "mbctl.cli"]


def _time(cmd: list[str]) -> float:
    t0 = time.perf_counter()
    subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
    return time.perf_counter() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=15)
    parser.add_argument("--module", action="store_true", help="Run python -m mbctl.cli.")
    args = parser.parse_args()
    mbctl = _mbctl(args.module)
    cmds = {
        "mbctl --help": [*mbctl, "--help"],
        "mbctl demo --help": [*mbctl, "demo", "--help"],
        "import mujoco, pinocchio": [sys.executable, "-c", "import mujoco, pinocchio"],
    }
    env_note = {k: os.environ[k] for k in ("MUJOCO_GL",) if k in os.environ}
    for cmd in cmds.values():
        _time(cmd)  # warm the file cache
    samples: dict[str, list[float]] = {k: [] for k in cmds}
    for _ in range(args.rounds):
        for name, cmd in cmds.items():
            samples[name].append(_time(cmd))
    med = {k: statistics.median(v) for k, v in samples.items()}
    base = samples["import mujoco, pinocchio"]
    load = os.getloadavg()
    print(f"{' '.join(Path(c).name for c in mbctl)}: {args.rounds} interleaved rounds, subprocesses; "
          f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}{'; ' + str(env_note) if env_note else ''}")
    for name, v in med.items():
        print(f"{name:<26}: {v * 1e3:7.1f} ms (range {min(samples[name]) * 1e3:.1f}-"
              f"{max(samples[name]) * 1e3:.1f})")
    for name in ("mbctl --help", "mbctl demo --help"):
        per_round = [a / b for a, b in zip(samples[name], base, strict=True)]
        label = "help/import" if name == "mbctl --help" else "demo help/import"
        ratio = med[name] / med["import mujoco, pinocchio"]
        verdict = ("ok" if ratio <= GOAL else "MISSED") if name == "mbctl --help" else ""
        print(f"ratio {label:<17}: {ratio:.2f}  (per-round {min(per_round):.2f}-{max(per_round):.2f})"
              f"{f'  goal <= {GOAL:g}x {verdict}' if verdict else ''}")


if __name__ == "__main__":
    main()
