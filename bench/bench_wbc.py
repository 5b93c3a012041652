"""Whole-body inverse dynamics on the G1: our controller per cycle, TSID in the same run, QP solvers.

    python bench/bench_wbc.py            # timings (needs MENAGERIE_ROOT; TSID if installed)
    python bench/bench_wbc.py --push     # also: the largest push impulse survived per direction

Timings are medians over the same 60 states of a squat run by our controller (so both controllers
see moving, loaded states), interleaved. TSID: ``pip install tsid`` (1.10 uses pin 4.1, as we do);
without it that part is skipped with a line saying so.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import qpsolvers

from mbctl.jobs.g1_wbc import G1_WBC, WBCParams, g1_whole_body
from mbctl.jobs.runner import run_job
from mbctl.robots import load_robot
from mbctl.robots.edits import position_to_motor
from mbctl.robots.g1 import crouched_start, with_palm_sites
from mbctl.robots.interface import RobotState
from mbctl.sim.simulator import Simulator

sys.path.insert(0, str(Path(__file__).parent))


def _states(robot, n: int = 60, stride: int = 10) -> list[RobotState]:
    """States of a squat under our controller: ``n`` states, every ``stride``-th cycle."""
    sim = Simulator(robot)
    sim.reset("stand")
    sim.set_state(crouched_start(robot), np.zeros(robot.pin_model.nv))
    wb = g1_whole_body(robot)
    wb.hold(sim.read_state())
    c0 = wb.com.target
    out = []
    for k in range(stride * n):
        t = sim.time_s
        wb.com.set_target(c0 - [0, 0, 0.04 * (1 - np.cos(np.pi * t))])
        state = sim.read_state()
        sim.step(wb.controller.compute(state))
        if k % stride == 0:
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


def _controller(robot, q0: np.ndarray, momentum: bool = True, warm_start: bool = True):
    """Our controller at rest at ``q0``: the job's task set, or without angular momentum (TSID's)."""
    wb = g1_whole_body(robot)
    ctrl = wb.controller
    ctrl.config = dataclasses.replace(ctrl.config, warm_start=warm_start)
    if not momentum:
        ctrl.remove_task(wb.momentum)
    wb.hold(RobotState(q0, np.zeros(robot.pin_model.nv), 0.0))
    return ctrl


#: Our controller on TSID's task set (no angular-momentum task): the ratio's numerator.
SAME_TASKS = "ours, TSID's tasks"


def timings(robot) -> None:
    states = _states(robot)
    q0 = crouched_start(robot)
    ctrls = {"ours": _controller(robot, q0), SAME_TASKS: _controller(robot, q0, momentum=False),
             "ours, cold start": _controller(robot, q0, warm_start=False)}
    qp_times: dict[str, list[float]] = {name: [] for name in ctrls}

    def ours(name):
        ctrl = ctrls[name]

        def run(st: RobotState) -> None:
            ctrl.compute(st)
            qp_times[name].append(ctrl.solution.qp_time_s)
        return run

    fns = {name: ours(name) for name in ctrls}
    try:
        from tsid_g1 import TsidG1

        tsid_ctrl = TsidG1(ctrls["ours"], q0)
        tau_tsid = tsid_ctrl.compute(q0, np.zeros(robot.pin_model.nv))  # joint order (idx_v - 6)
        same = ctrls[SAME_TASKS]
        same.compute(RobotState(q0, np.zeros(robot.pin_model.nv), 0.0))
        tau_ours = same.solution.tau  # actuator order
        tau_tsid = tau_tsid[np.asarray(same.joints.idx_v) - 6]
        mg = same.state.mass * 9.81
        print(f"TSID at rest: sum f_z / (m g) - 1 = {abs(tsid_ctrl.normal_force_n() - mg) / mg:.2e}; "
              f"torques against ours: max |diff| {np.abs(tau_ours - tau_tsid).max():.2e} N m "
              f"(largest torque {np.abs(tau_ours).max():.1f} N m)")
        fns["tsid"] = lambda st: tsid_ctrl.compute(np.asarray(st.q), np.asarray(st.v))
    except ImportError:
        print("TSID not importable (see bench/README.md for building it): its column is skipped")
    except MemoryError:
        # seen with the PyPI tsid 1.10 wheel + pin 4.1: RobotWrapper(model, ...) raises MemoryError
        # even for pin.buildSampleModelHumanoid() (a binary mismatch of the wheels)
        print("TSID imports but its RobotWrapper(pin.Model) fails (MemoryError: the PyPI tsid 1.10 "
              "wheel; build it from source, bench/README.md): its column is skipped")
    medians: dict[str, list[float]] = {name: [] for name in fns}
    for _ in range(5):  # interleaved rounds
        for name, fn in fns.items():
            medians[name].append(_per_cycle(fn, states, repeats=2))
    res = {k: statistics.median(v) for k, v in medians.items()}
    solver = ctrls["ours"].config.solver
    print(f"G1 whole-body ID per cycle (Pinocchio terms + QP build + solve), median over {len(states)} "
          f"squat states x 10, load average {os.getloadavg()[0]:.1f}:")
    for name in ctrls:
        print(f"  {name + f' (qpsolvers/{solver})':38s} {res[name] * 1e6:6.0f} us; QP solve alone "
              f"{statistics.median(qp_times[name]) * 1e6:4.0f} us  (goal 400 us)")
    if "tsid" in res:
        print(f"  {'TSID 1.10 (C++, eiquadprog-fast)':38s} {res['tsid'] * 1e6:6.0f} us   ratio ours/TSID "
              f"{res[SAME_TASKS] / res['tsid']:.2f}x on the same task set")
    # warm start on consecutive cycles (the job's case)
    consecutive = _states(robot, n=200, stride=1)
    warm = {w: _controller(robot, q0, warm_start=w) for w in (True, False)}
    t_qp: dict[bool, list[float]] = {True: [], False: []}
    for _ in range(3):
        for w, ctrl in warm.items():
            for st in consecutive:
                ctrl.compute(st)
                t_qp[w].append(ctrl.solution.qp_time_s)
    warm_us, cold_us = (statistics.median(t_qp[w]) * 1e6 for w in (True, False))
    print(f"warm start on {len(consecutive)} consecutive cycles: QP solve {warm_us:.0f} us warm against "
          f"{cold_us:.0f} us cold")
    # the QP backend: the same problem through each installed solver
    ctrl = ctrls["ours"]
    ctrl.compute(states[-1])
    problem = _last_problem(ctrl, states[-1])
    print(f"QP backends on the same G1 problem ({ctrl.n_x} variables):")
    for solver in ("daqp", "proxqp", "osqp", "quadprog"):
        if solver not in qpsolvers.available_solvers:
            print(f"  {solver:8s} not installed")
            continue
        t = []
        for _ in range(50):
            t0 = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # osqp: "converted to csc_matrix"
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
