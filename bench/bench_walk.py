"""Walking on the G1 (issue 28): the walking cycle against the standing WBC cycle, the step-adaptation
QP, and a 20 s walk against real time.

    python bench/bench_walk.py                 # all three (needs MENAGERIE_ROOT)
    python bench/bench_walk.py --walk-s 20     # the walk's simulated time (default 20 s)
    python bench/bench_walk.py --gait normal   # the normal gait's walker (default: the job's, quick)

Cycle timings are medians over the same states of a walk at 0.3 m/s (the walker's own, every
cycle from its first, so a fresh walker replaying them decides as the recording one did and its
per-cycle reuse of plans holds as in the loop), replayed into fresh controllers in interleaved
rounds: the walking controller's
whole ``compute`` (gait, footsteps, DCM plan, step adaptation, task targets, the QP) against the
standing controller's (``standing_controller``, the g1-wbc stand task set) on the same states, in
thread CPU time and wall time; beside them a walker planning its footsteps every cycle
(``replan_period_s=0``: it replays the same states, deciding as a walker planning every cycle
would on them) and one whose QP skips the force-space QP (``WBCConfig(force_space=False)``: daqp
on the QP in vdot and forces). Then the walking cycle's two parts, in wall time: the walker's own
code and its whole-body controller's compute (timed inside it), the latter against the standing
WBC's. The step-adaptation QP is timed on the DCM errors of a push; the
walk is ``g1-walk forward`` through the job (CSV, plots), wall time over simulated time. The load
average is printed with every figure: the machine is shared, so only ratios within a run compare.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from functools import partial
from pathlib import Path

import numpy as np

from mbctl.control.loop import run
from mbctl.control.wbc import WalkingConfig, WalkingController, WBCConfig, quick_gait, standing_controller
from mbctl.jobs.g1_walk import G1_WALK, WalkParams, prepare
from mbctl.jobs.runner import Job, run_job
from mbctl.planners import Footstep
from mbctl.robots import load_robot
from mbctl.robots.edits import position_to_motor
from mbctl.robots.g1 import FEET, KEYFRAME, PELVIS, TORSO, crouched_start, with_palm_sites
from mbctl.sim.simulator import Simulator

sys.path.insert(0, str(Path(__file__).parent))
from harness import interleaved  # noqa: E402

#: The walker's gait (``--gait``: the job's ``--gait``).
GAIT = {"gait": "quick"}


def _walker(robot, q0, force_space: bool = True, **options):
    options["wbc"] = WBCConfig(on_infeasible="damp", force_space=force_space)
    config = quick_gait(**options) if GAIT["gait"] == "quick" else WalkingConfig(**options)
    return WalkingController(robot, FEET, PELVIS, TORSO, q0, config)


def _walk_states(robot, q0, seconds: float = 4.0):
    """Every state of a 0.3 m/s walk under the walker, from its first cycle."""
    sim = Simulator(robot)
    sim.reset(KEYFRAME)
    sim.set_state(q0, np.zeros(robot.nv))
    walker = _walker(robot, q0)
    walker.set_command((0.3, 0.0, 0.0))
    states = []

    def keep(k, state, reference, command) -> None:
        states.append(state)

    run(sim, walker, None, seconds, on_step=keep)
    return states


def _stand_states(robot, q0, n: int, stride: int = 5):
    """``n`` states of the standing controller squatting 4 cm at 0.5 Hz (bench_wbc's workload)."""
    sim = Simulator(robot)
    sim.reset(KEYFRAME)
    sim.set_state(q0, np.zeros(robot.nv))
    standing = standing_controller(robot, FEET, PELVIS, TORSO)
    standing.hold(sim.read_state())
    c0 = standing.com.target
    states = []
    for k in range(stride * n):
        standing.com.set_target(c0 - [0, 0, 0.02 * (1 - np.cos(np.pi * sim.time_s))])
        state = sim.read_state()
        sim.send(standing.controller.compute(state))
        sim.sync()
        if k % stride == 0:
            states.append(state)
    return standing, states


def cycles(robot, q0, rounds: int) -> None:
    """The walking cycle on walking states against the standing WBC cycle on standing (squat) states."""
    states = _walk_states(robot, q0)
    walker = _walker(robot, q0)
    every_cycle = _walker(robot, q0, replan_period_s=0.0)  # footsteps planned every cycle
    no_force_space = _walker(robot, q0, force_space=False)  # daqp on the QP in vdot and forces
    for w in (walker, every_cycle, no_force_space):
        w.set_command((0.3, 0.0, 0.0))
    standing, stand_states = _stand_states(robot, q0, len(states), stride=1)

    def replay(w) -> None:
        w.reset()  # each round replays the walk from its start
        for s in states:
            w.compute(s)

    def run_standing() -> None:
        for s in stand_states:
            standing.controller.compute(s)

    for timer, label in ((time.thread_time, "thread CPU"), (time.perf_counter, "wall")):
        t = interleaved({"walk": partial(replay, walker), "every": partial(replay, every_cycle),
                         "no_fs": partial(replay, no_force_space), "stand": run_standing},
                        repeats=rounds, timer=timer)
        n = len(states)
        print(f"cycle ({label}, median of {rounds} rounds over {n} states each): walking "
              f"{t['walk'] / n * 1e6:.0f} us (0.3 m/s), standing WBC {t['stand'] / n * 1e6:.0f} us (squat), "
              f"ratio {t['walk'] / t['stand']:.2f} (target <= 1.2); footsteps planned every cycle "
              f"(replan_period_s=0) {t['every'] / n * 1e6:.0f} us, ratio {t['every'] / t['stand']:.2f}; "
              f"without the force-space QP {t['no_fs'] / n * 1e6:.0f} us "
              f"({t['walk'] / t['no_fs']:.2f}x with it); load {os.getloadavg()[0]:.2f}")


def split(robot, q0, rounds: int) -> None:
    """The walking cycle's two parts on the same states (wall): the walker's own code and its WBC's compute.

    The WBC's part is timed inside the walker's compute (a wrapper of ``wbc.compute``); beside the
    standing WBC's whole compute, it says how much of the ratio is the QP's harder problem in
    single support and how much the planning.
    """
    states = _walk_states(robot, q0)
    walker = _walker(robot, q0)
    walker.set_command((0.3, 0.0, 0.0))
    standing, stand_states = _stand_states(robot, q0, len(states), stride=1)
    inner = walker.wbc.compute
    spent = [0.0]

    def timed(state):
        t0 = time.perf_counter()
        try:
            return inner(state)
        finally:
            spent[0] += time.perf_counter() - t0

    walker.wbc.compute = timed
    walks, wbcs, stands = [], [], []
    for _ in range(rounds):
        walker.reset()
        spent[0] = 0.0
        t0 = time.perf_counter()
        for s in states:
            walker.compute(s)
        walks.append(time.perf_counter() - t0)
        wbcs.append(spent[0])
        t0 = time.perf_counter()
        for s in stand_states:
            standing.controller.compute(s)
        stands.append(time.perf_counter() - t0)
    n = len(states)
    walk, wbc, stand = (statistics.median(x) / n * 1e6 for x in (walks, wbcs, stands))
    print(f"walking cycle's parts (wall, median of {rounds} rounds over {n} states): the walker's own "
          f"code {walk - wbc:.0f} us, its WBC {wbc:.0f} us ({wbc / stand:.2f}x the standing WBC's "
          f"{stand:.0f} us); load {os.getloadavg()[0]:.2f}")


def adaptation_qp(robot, q0, repeats: int = 2000) -> None:
    """The step-adaptation QP on DCM errors outside the tube (a push's), median solve and call."""
    walker = _walker(robot, q0)
    stance = Footstep(FEET[1], -1, np.array([0.0, -0.118, 0.0]), 0.0)
    nominal = walker.planner.next_footstep(stance, walker.planner.clamp((0.3, 0.0, 0.0)).applied)
    rng = np.random.default_rng(3)
    errors = rng.uniform(-0.15, 0.15, (repeats, 2))
    calls, solves = [], []
    for e in errors:
        t0 = time.perf_counter()
        out = walker.adapter.adapt(stance, nominal, e, 0.3)
        calls.append(time.perf_counter() - t0)
        if out.outside_tube:
            solves.append(out.solve_time_s)
    print(f"step-adaptation QP (daqp through control/qp.py): solve median "
          f"{statistics.median(solves) * 1e6:.1f} us, whole adapt() median "
          f"{statistics.median(calls) * 1e6:.1f} us over {len(solves)} errors outside the tube (target <= "
          f"100 us); load {os.getloadavg()[0]:.2f}")


def walk(robot, seconds: float, folder: Path) -> None:
    """``g1-walk forward`` through the job: wall time against simulated time."""
    job = Job(G1_WALK.name, partial(prepare, robot=robot))
    t0 = time.perf_counter()
    record = run_job(job, WalkParams("forward", "0.3", seconds, gait=GAIT["gait"]), folder, quiet=True)
    wall = time.perf_counter() - t0
    v = record.values
    print(f"g1-walk forward --speed 0.3 --duration {seconds:g} --gait {GAIT['gait']}: {wall:.1f} s wall for "
          f"{seconds:g} s "
          f"simulated = {wall / seconds:.2f} x real time (target <= 1.5), fell {v['fell']}, "
          f"{v['distance_m']:.2f} m; load {os.getloadavg()[0]:.2f}")


def main() -> int:
    """Run the benchmarks."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--walk-s", type=float, default=20.0, help="simulated time of the timed walk (s)")
    parser.add_argument("--rounds", type=int, default=5, help="interleaved rounds of the cycle timings")
    parser.add_argument("--output", type=Path, default=Path("out/bench_walk"), help="the walk's run folder")
    parser.add_argument("--gait", choices=("quick", "normal"), default="quick", help="the walker's gait")
    args = parser.parse_args()
    GAIT["gait"] = args.gait
    print(f"the {args.gait} gait's walker")
    robot = position_to_motor(with_palm_sites(load_robot("g1")))
    q0 = crouched_start(robot)
    cycles(robot, q0, args.rounds)
    split(robot, q0, args.rounds)
    adaptation_qp(robot, q0)
    walk(robot, args.walk_s, args.output)
    return 0


if __name__ == "__main__":
    sys.exit(main())
