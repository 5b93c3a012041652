"""Whole-body inverse dynamics on the G1: our controller per cycle, TSID in the same run, QP solvers.

    python bench/bench_wbc.py            # timings (needs MENAGERIE_ROOT; TSID if installed)
    python bench/bench_wbc.py --push     # also: the largest push impulse survived per direction

Timings are medians over the same 60 states of a squat run by our controller (so both controllers
see moving, loaded states), interleaved. TSID: ``pip install tsid`` (1.10 uses pin 4.1, as we do);
without it that part is skipped with a line saying so.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import qpsolvers

from mbctl.jobs.g1_wbc import G1_WBC, WBCParams, crouched_start, g1_whole_body
from mbctl.jobs.robot_constants import with_palm_sites
from mbctl.jobs.runner import run_job
from mbctl.robots import load_robot
from mbctl.robots.edits import position_to_motor
from mbctl.robots.interface import RobotState
from mbctl.sim.simulator import Simulator

sys.path.insert(0, str(Path(__file__).parent))


def _states(robot, n: int = 60) -> list[RobotState]:
    """States of the first 1.2 s of a squat under our controller, every 10th cycle."""
    sim = Simulator(robot)
    sim.reset("stand")
    sim.set_state(crouched_start(robot), np.zeros(robot.pin_model.nv))
    wb = g1_whole_body(robot)
    state = sim.read_state()
    wb.controller.reset_contacts(state)
    s = wb.controller.state
    c0 = s.com().copy()
    wb.pelvis.set_reference(s.frame_pose(wb.pelvis.fid))
    wb.torso.set_reference(s.frame_pose(wb.torso.fid))
    wb.posture.set_reference(state.q)
    out = []
    for k in range(10 * n):
        t = sim.time_s
        wb.com.set_reference(c0 - [0, 0, 0.04 * (1 - np.cos(np.pi * t))])
        state = sim.read_state()
        sim.step(wb.controller.compute(state, dt_s=sim.control_period_s))
        if k % 10 == 0:
            out.append(state)
    return out


def _per_cycle(fn, states, repeats: int = 5) -> float:
    samples = []
    for _ in range(repeats):
        for st in states:
            t0 = time.perf_counter()
            fn(st)
            samples.append(time.perf_counter() - t0)
    return statistics.median(samples)


def timings(robot) -> None:
    states = _states(robot)
    wb = g1_whole_body(robot)
    ctrl = wb.controller
    q0 = crouched_start(robot)
    ctrl.reset_contacts(RobotState(q0, np.zeros(robot.pin_model.nv), 0.0))
    s = ctrl.state
    wb.com.set_reference(s.com().copy())
    wb.pelvis.set_reference(s.frame_pose(wb.pelvis.fid))
    wb.torso.set_reference(s.frame_pose(wb.torso.fid))
    wb.posture.set_reference(q0)
    qp_times: list[float] = []

    def ours(st: RobotState) -> None:
        ctrl.compute(st)
        qp_times.append(ctrl.solution.qp_time_s)

    fns = {"ours": ours}
    try:
        from tsid_g1 import TsidG1

        tsid_ctrl = TsidG1(ctrl, q0)
        tsid_ctrl.compute(q0, np.zeros(robot.pin_model.nv))
        rel = abs(tsid_ctrl.normal_force_n() - s.mass * 9.81) / (s.mass * 9.81)
        print(f"TSID at rest: sum f_z / (m g) - 1 = {rel:.2e} (a like-for-like solution)")
        fns["tsid"] = lambda st: tsid_ctrl.compute(np.asarray(st.q), np.asarray(st.v))
    except ImportError:
        print("TSID not installed (pip install tsid): its column is skipped")
    except MemoryError:
        # seen with tsid 1.10 + pin 4.1 from PyPI: RobotWrapper(model, ...) raises MemoryError
        # even for pin.buildSampleModelHumanoid() in a clean venv (a binary mismatch of the wheels)
        print("TSID installed but its RobotWrapper(pin.Model) fails (MemoryError, tsid 1.10 wheels): "
              "its column is skipped")
    medians = {name: [] for name in fns}
    for _ in range(3):  # interleaved rounds
        for name, fn in fns.items():
            medians[name].append(_per_cycle(fn, states, repeats=2))
    res = {k: statistics.median(v) for k, v in medians.items()}
    print(f"G1 whole-body ID per cycle (Pinocchio terms + QP build + solve), median over {len(states)} "
          "squat states:")
    print(f"  ours (qpsolvers/{ctrl.config.solver}): {res['ours'] * 1e6:7.0f} us   (goal 400 us); "
          f"QP solve alone {statistics.median(qp_times) * 1e6:.0f} us")
    if "tsid" in res:
        print(f"  TSID 1.10 (C++, HQuadProgFast):  {res['tsid'] * 1e6:7.0f} us   ratio ours/TSID "
              f"{res['ours'] / res['tsid']:.2f}x")
    # the QP backend: the same problem through each installed solver
    ctrl.compute(states[-1])
    problem = _last_problem(ctrl, states[-1])
    print("QP backends on the same G1 problem (59 variables):")
    for solver in ("daqp", "proxqp", "osqp", "quadprog"):
        if solver not in qpsolvers.available_solvers:
            print(f"  {solver:8s} not installed")
            continue
        t = []
        for _ in range(50):
            t0 = time.perf_counter()
            sol = qpsolvers.solve_problem(problem, solver=solver)
            t.append(time.perf_counter() - t0)
        ref = qpsolvers.solve_problem(problem, solver="daqp").x
        print(f"  {solver:8s} {statistics.median(t) * 1e6:7.0f} us, found={sol.found}, "
              f"primal residual {sol.primal_residual():.1e}, |x - x_daqp| {np.abs(sol.x - ref).max():.1e}")


def _last_problem(ctrl, state):
    """Rebuild the QP of ``state`` by solving with a spy solver name (qpsolvers.Problem)."""
    captured = {}
    original = qpsolvers.solve_problem

    def spy(problem, solver, **kw):
        captured["p"] = problem
        return original(problem, solver=solver, **kw)

    qpsolvers.solve_problem = spy
    try:
        ctrl.compute(state)
    finally:
        qpsolvers.solve_problem = original
    return captured["p"]


#: Foot slip [m] above which a push counts as not withstood.
MAX_SLIP_M = 0.02


def push_limits() -> None:
    """Bisection on the impulse per direction (0.5 N s resolution), one push at t = 1 s."""
    print("largest push impulse survived (force on the pelvis held 0.1 s, no stepping; survived = "
          f"not fallen within 2 s and feet slipped < {MAX_SLIP_M * 1e3:g} mm):")
    for angle in range(0, 360, 45):
        lo, hi = 0.0, 40.0
        while hi - lo > 0.5:
            mid = 0.5 * (lo + hi)
            rec = run_job(G1_WBC, WBCParams("push", impulse=mid, direction=float(angle)),
                          Path("out/bench_push") / f"{angle}")
            # survived: did not fall and the feet held (a sideways shove can slide the robot
            # across the floor without a fall: that is not standing the push)
            held = rec.values.get("fell") is False and rec.values["max_foot_slip_m"] < MAX_SLIP_M
            lo, hi = (mid, hi) if held else (lo, mid)
        print(f"  direction {angle:3d} deg: {lo:5.1f} N s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--push", action="store_true", help="Also bisect the largest push per direction.")
    args = parser.parse_args()
    robot = position_to_motor(with_palm_sites(load_robot("g1")))
    timings(robot)
    if args.push:
        push_limits()


if __name__ == "__main__":
    main()
