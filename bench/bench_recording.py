"""CSV recording cost: one G1 row and the g1-stand job's loop against its bare control loop.

Run: MENAGERIE_ROOT=/path/to/menagerie python bench/bench_recording.py [--rounds 7] [--duration 10]

Figures, all measured in this run (rounds interleaved, medians):

* ``row``: microseconds per G1 row (131 columns: time, q_ref, full q, v, torques, base_z_m)
  written as the G1 jobs write it (``LoopRows`` into the run's ``CsvStream``), amortised over
  every row of a ``--duration`` run, closing the file included; beside it the bare control cycle
  of the same robot, controller and steps (``control.loop.run``, no recording).
* ``job loop / bare``: the g1-stand job's loop (``jobs.g1._loop``: CSV rows, the trajectory
  observer kept for replay, progress; its ``wall_time_s``) plus closing the CSV, against
  ``control.loop.run`` with the same controller, reference and steps and nothing recorded. The
  once-per-run files (``model.xml`` when the plant is attached, ``trajectory.npz`` at the end)
  are left out: they do not grow with the run.

Goals (issue 21): a row <= 15 us; the job's loop <= 1.3x the bare loop.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

from mbctl.control.controller import joint_reference  # noqa: E402
from mbctl.control.gains import PDGains, gains_from_frequency  # noqa: E402
from mbctl.control.loop import run  # noqa: E402
from mbctl.control.pd_gravity import PDGravity  # noqa: E402
from mbctl.jobs.g1 import _base_z_index, _loop, stance_inertia  # noqa: E402
from mbctl.jobs.recording import LoopRows, command_columns  # noqa: E402
from mbctl.jobs.runner import RunContext  # noqa: E402
from mbctl.robots import load_robot  # noqa: E402
from mbctl.robots.commands import Command, CommandKind  # noqa: E402
from mbctl.robots.edits import position_to_motor  # noqa: E402
from mbctl.robots.g1 import KEYFRAME  # noqa: E402
from mbctl.robots.interface import RobotState  # noqa: E402
from mbctl.sim.recorder import CsvStream  # noqa: E402
from mbctl.sim.simulator import Simulator  # noqa: E402

GOAL_ROW_US = 15.0
GOAL_JOB_RATIO = 1.3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--duration", type=float, default=10.0,
                        help="Simulated seconds per run (g1-stand's default).")
    args = parser.parse_args()

    robot = position_to_motor(load_robot("g1"))
    q0 = robot.keyframe_q(KEYFRAME)
    probe = PDGravity(robot, PDGains(np.ones(1), np.ones(1)))
    gains = gains_from_frequency(10.0, 1.0, stance_inertia(robot, q0, probe.joints))
    controller = PDGravity(robot, gains)
    reference = joint_reference(q0[controller.joint_map.idx_q])
    sim = Simulator(robot)
    joints = controller.joints

    def bare() -> float:
        sim.reset(KEYFRAME)
        t0 = time.perf_counter()
        run(sim, controller, reference, args.duration)
        return time.perf_counter() - t0

    # the states, commands and reference of a real run, replayed into the stream
    sim.reset(KEYFRAME)
    log = run(sim, controller, reference, args.duration)
    cycles = log.cycles
    states = [RobotState(log.q[k], log.v[k], float(log.t_s[k])) for k in range(cycles)]
    commands = [Command(CommandKind.TORQUE, log.command[k], joints) for k in range(cycles)]
    header = LoopRows.header(robot, [f"q_ref_{j}_rad" for j in joints], command_columns(joints, "N_m"),
                             ["base_z_m"])
    zi = _base_z_index(robot)

    def extra(state: RobotState) -> list[float]:
        return [float(state.q[zi])]

    tmp = Path(tempfile.mkdtemp(prefix="bench_recording."))

    def rows() -> float:
        t0 = time.perf_counter()
        stream = CsvStream(tmp / "rows.csv", header)
        on_step = LoopRows(stream, len(joints), extra)
        for k in range(cycles):
            on_step(k, states[k], reference, commands[k])
        stream.close()
        return time.perf_counter() - t0

    def job_loop() -> float:
        folder = tmp / "job"
        folder.mkdir(exist_ok=True)
        ctx = RunContext(folder, "g1-stand")
        sim.reset(KEYFRAME)
        log = _loop(ctx, sim, controller, reference, args.duration, "N_m", "g1-stand", base_z=True)
        t0 = time.perf_counter()
        for stream in ctx._streams:
            stream.close()
        elapsed = log.wall_time_s + time.perf_counter() - t0
        ctx.close_streams()  # trajectory.npz and model.xml: once per run, not per cycle
        return elapsed

    fns = {"bare": bare, "rows": rows, "job": job_loop}
    samples: dict[str, list[float]] = {k: [] for k in fns}
    for fn in fns.values():
        fn()  # warm-up
    for _ in range(args.rounds):
        for name, fn in fns.items():
            samples[name].append(fn())
    med = {k: statistics.median(v) for k, v in samples.items()}
    ratios = [j / b for j, b in zip(samples["job"], samples["bare"], strict=True)]
    print(f"G1, {cycles} control cycles ({args.duration:g} s), {len(header)} columns, "
          f"{args.rounds} interleaved rounds; load average {os.getloadavg()[0]:.2f} "
          f"{os.getloadavg()[1]:.2f} {os.getloadavg()[2]:.2f}")
    print(f"bare control cycle      : {med['bare'] / cycles * 1e6:7.2f} us")
    row_us = med["rows"] / cycles * 1e6
    print(f"row (amortised)         : {row_us:7.2f} us   goal <= {GOAL_ROW_US:g} us "
          f"{'ok' if row_us <= GOAL_ROW_US else 'MISSED'}")
    print(f"ratio row/cycle         : {med['rows'] / med['bare']:7.2f}   (a row in control cycles, same run)")
    ratio = med["job"] / med["bare"]
    print(f"job loop                : {med['job'] / cycles * 1e6:7.2f} us per cycle")
    print(f"ratio job/bare          : {ratio:7.2f}x  goal <= {GOAL_JOB_RATIO:g}x "
          f"{'ok' if ratio <= GOAL_JOB_RATIO else 'MISSED'} (per-round range "
          f"{min(ratios):.2f}-{max(ratios):.2f})")


if __name__ == "__main__":
    main()
