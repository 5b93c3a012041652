"""Whole-body inverse dynamics on the G1: our controller per cycle, TSID in the same run, QP paths,
the job's overhead, and the cycle against the number of contact points.

    python bench/bench_wbc.py            # timings (needs MENAGERIE_ROOT; TSID if built)
    python bench/bench_wbc.py --push     # also: the largest push impulse survived per direction
    python bench/bench_wbc.py --section job   # only the g1-wbc job's cycle overhead (3 runs)

Timings are medians over the same 60 states of a squat run by our controller (so both controllers
see moving, loaded states), interleaved rounds. TSID: ``bench/build_tsid.sh`` then
``export PYTHONPATH=...`` (see bench/README.md); without it that column is skipped with a line
saying so. Every ratio is measured in the same run; the load average is printed with it.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import qpsolvers

from mbctl.control.wbc import FootContact, WholeBodyController, foot_contact_from_model, standing_controller
from mbctl.jobs.g1_wbc import G1_WBC, WBCParams, g1_whole_body
from mbctl.jobs.runner import run_job
from mbctl.robots import load_robot
from mbctl.robots.edits import position_to_motor
from mbctl.robots.g1 import FEET, PELVIS, TORSO, crouched_start, with_palm_sites
from mbctl.robots.interface import RobotState
from mbctl.sim.simulator import Simulator

sys.path.insert(0, str(Path(__file__).parent))


def _states(robot, n: int = 60, stride: int = 10) -> list[RobotState]:
    """States of a squat under our controller: ``n`` states, every ``stride``-th cycle."""
    sim = Simulator(robot)
    sim.reset("stand")
    sim.set_state(crouched_start(robot), np.zeros(robot.nv))
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


def _controller(robot, q0: np.ndarray, momentum: bool = True, daqp_only: bool = False,
                points_per_foot: int | None = None) -> WholeBodyController:
    """Our controller at rest at ``q0``: the job's task set, or without angular momentum (TSID's).

    ``daqp_only`` skips the equality-constrained fast path (daqp on every cycle, as when an
    inequality binds); ``points_per_foot`` replaces each sole's 4 corners by a grid of points.
    """
    contacts = None
    if points_per_foot is not None:
        contacts = [_grid_foot(foot_contact_from_model(robot, f), points_per_foot) for f in FEET]
    wb = standing_controller(robot, FEET, PELVIS, TORSO, contacts=contacts)
    ctrl = wb.controller
    if not momentum:
        ctrl.remove_task(wb.momentum)
    if daqp_only:
        qp = ctrl._qp  # the bench times the general path on purpose (a private hook)
        qp.solve = lambda m_eq: qp._daqp(np.arange(m_eq), 0)[0]  # type: ignore[method-assign]
    wb.hold(RobotState(q0, np.zeros(robot.nv), 0.0))
    return ctrl


def _grid_foot(contact: FootContact, n: int) -> FootContact:
    """The same sole with ``n`` points: a grid over the rectangle of its corners (n = 4, 8, 16...)."""
    lo, hi = contact.points_F.min(0), contact.points_F.max(0)
    cols = {4: 2, 8: 4, 16: 4}[n]
    rows = n // cols
    xs, ys = np.linspace(lo[0], hi[0], cols), np.linspace(lo[1], hi[1], rows)
    pts = np.array([[x, y, lo[2]] for x in xs for y in ys])
    return FootContact(contact.name, contact.frame, pts, contact.mu, contact.geoms)


#: Our controller on TSID's task set (no angular-momentum task): the ratio's numerator.
SAME_TASKS = "ours, TSID's tasks"


def timings(robot) -> dict[str, float]:
    states = _states(robot)
    q0 = crouched_start(robot)
    ctrls = {"ours": _controller(robot, q0), SAME_TASKS: _controller(robot, q0, momentum=False),
             "ours, daqp every cycle": _controller(robot, q0, daqp_only=True)}
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
        tau_tsid = tsid_ctrl.compute(q0, np.zeros(robot.nv))  # joint order (idx_v - 6)
        same = ctrls[SAME_TASKS]
        same.compute(RobotState(q0, np.zeros(robot.nv), 0.0))
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
        print("TSID imports but its RobotWrapper(pin.Model) fails (MemoryError: the PyPI tsid 1.10 "
              "wheel; build it from source, bench/README.md): its column is skipped")
    medians: dict[str, list[float]] = {name: [] for name in fns}
    for _ in range(5):  # interleaved rounds
        for name, fn in fns.items():
            medians[name].append(_per_cycle(fn, states, repeats=2))
    res = {k: statistics.median(v) for k, v in medians.items()}
    fast = ctrls["ours"].fast_path_cycles / max(1, ctrls["ours"].fast_path_cycles + ctrls["ours"].daqp_cycles)
    print(f"G1 whole-body ID per cycle (Pinocchio terms, task rows, QP), median over {len(states)} squat "
          f"states x 10, load average {os.getloadavg()[0]:.1f}:")
    for name in ctrls:
        print(f"  {name:34s} {res[name] * 1e6:6.0f} us; QP {statistics.median(qp_times[name]) * 1e6:4.0f} us")
    print(f"  (equality-constrained fast path taken in {fast * 100:.0f} % of these states)")
    if "tsid" in res:
        print(f"  {'TSID 1.10 (C++, eiquadprog-fast)':34s} {res['tsid'] * 1e6:6.0f} us")
        daqp_ratio = res["ours, daqp every cycle"] / res["tsid"]
        print(f"  ratio ours/TSID : {res[SAME_TASKS] / res['tsid']:.2f} on the same task set "
              f"(goal <= 0.8, issue 30); with daqp every cycle {daqp_ratio:.2f}")
    _backends(ctrls["ours"], states[-1])
    return {"bench_controller_us": res["ours"] * 1e6}


def _backends(ctrl: WholeBodyController, state: RobotState) -> None:
    """The same problem through each QP path and backend."""
    ctrl.compute(state)
    qp = ctrl._qp  # the bench reads the last cycle's buffers (a private hook)
    m_eq = ctrl._n_unact + 6 * sum(cs.active for cs in ctrl.contacts.values())
    problem = qp.problem(m_eq)
    ref = qpsolvers.solve_problem(problem, solver="daqp").x
    paths = {"structured (fast path)": lambda: qp.solve(m_eq),
             "daqp direct (two-sided rows)": lambda: qp._daqp(np.arange(m_eq), 0)[0]}
    print(f"QP on the same G1 problem ({ctrl.n_x} variables, {m_eq} equalities):")
    for name, fn in paths.items():
        t = []
        for _ in range(200):
            t0 = time.perf_counter()
            x = fn().x
            t.append(time.perf_counter() - t0)
        print(f"  {name:30s} {statistics.median(t) * 1e6:7.0f} us, |x - x_daqp| {np.abs(x - ref).max():.1e}")
    for solver in ("daqp", "proxqp", "osqp"):
        if solver not in qpsolvers.available_solvers:
            print(f"  {'qpsolvers/' + solver:30s} not installed")
            continue
        t = []
        for _ in range(50):
            t0 = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # osqp: "converted to csc_matrix"
                sol = qpsolvers.solve_problem(problem, solver=solver)
            t.append(time.perf_counter() - t0)
        print(f"  {'qpsolvers/' + solver:30s} {statistics.median(t) * 1e6:7.0f} us, found={sol.found}, "
              f"primal residual {sol.primal_residual():.1e}, |x - x_daqp| {np.abs(sol.x - ref).max():.1e}")


def _after_a_physics_step(robot) -> float:
    """Our controller per cycle when one MuJoCo step of the G1 runs between its calls, as in a job.

    The plant's step touches a few hundred kB of MuJoCo's data and evicts the controller's from the
    core's caches: what a controller running beside its plant in one process pays, job or not.
    """
    states = _states(robot)
    ctrl = _controller(robot, crouched_start(robot))
    sim = Simulator(robot)
    sim.reset("stand")
    sim.set_state(crouched_start(robot), np.zeros(robot.nv))
    samples = []
    for _ in range(5):
        for st in states:
            sim.step()
            t0 = time.perf_counter()
            ctrl.compute(st)
            samples.append(time.perf_counter() - t0)
    return statistics.median(samples)


def job_overhead(runs: int = 3, duration_s: float = 4.0) -> list[tuple[float, ...]]:
    """The g1-wbc squat job, ``runs`` times: (controller, cycle, physics step, overhead) medians and the
    overhead's mean [us] per run.

    The overhead is the cycle's time beyond its controller and its physics step (targets, state,
    command, plant monitor, CSV row, loop): the job's ``cycle_overhead_median_us``, the median of
    (cycle - controller - physics step) per cycle, and ``cycle_overhead_mean_us``, its mean (the
    log's batches and the CSV's flushes in it: the figure the median alone would hide); before
    those keys existed, the difference of the three medians (and NaN).
    """
    rows = []
    for k in range(runs):
        rec = run_job(G1_WBC, WBCParams("squat", duration=duration_s), Path("out/bench_wbc_job") / str(k),
                      quiet=True)
        v = rec.values
        ctrl, cycle, step = (v["controller_time_median_us"], v["cycle_time_median_us"],
                             v["physics_step_time_median_us"])
        rows.append((ctrl, cycle, step, v.get("cycle_overhead_median_us", cycle - ctrl - step),
                     v.get("cycle_overhead_mean_us", float("nan"))))
    return rows


def _spread(xs) -> str:
    xs = list(xs)
    return f"{statistics.median(xs):.0f} us ({min(xs):.0f}-{max(xs):.0f})"


def print_job_overhead(rows: list[tuple[float, ...]]) -> None:
    """The job's cycle overhead, median and range over the runs."""
    print(f"g1-wbc squat job cycle overhead ({len(rows)} runs; median (range) of the runs' medians), "
          f"load average {os.getloadavg()[0]:.1f}:")
    print(f"  cycle {_spread(r[1] for r in rows)}, controller {_spread(r[0] for r in rows)}, "
          f"physics step {_spread(r[2] for r in rows)}")
    print(f"  overhead (cycle - controller - physics step, per cycle) {_spread(r[3] for r in rows)} median, "
          f"{_spread(r[4] for r in rows)} mean (goal <= 40 us idle: targets, state, command, plant monitor, "
          "CSV row, loop)")
    print(f"  difference of the medians, cycle - controller - physics step: "
          f"{_spread(r[1] - r[0] - r[2] for r in rows)}")


def job_ratios(robot, bench_controller_us: float) -> None:
    """The controller inside the g1-wbc job against the bench, and the job's cycle against the controller."""
    rows = job_overhead()
    ctrl_us = statistics.median(r[0] for r in rows)
    cycle_us = statistics.median(r[1] for r in rows)
    step_us = statistics.median(r[2] for r in rows)
    stepped_us = _after_a_physics_step(robot) * 1e6
    print(f"g1-wbc squat 4 s (3 runs, medians), load average {os.getloadavg()[0]:.1f}:")
    print(f"  controller in the job {ctrl_us:.0f} us / in this bench {bench_controller_us:.0f} us : "
          f"{ctrl_us / bench_controller_us:.2f} (goal <= 1.1)")
    print(f"  controller in this bench with one physics step between calls {stepped_us:.0f} us : "
          f"{stepped_us / bench_controller_us:.2f} of the bench's; the job's / this: "
          f"{ctrl_us / stepped_us:.2f}")
    print(f"  job cycle {cycle_us:.0f} us / its controller {ctrl_us:.0f} us : {cycle_us / ctrl_us:.2f} "
          "(goal <= 1.3; the cycle: state, controller, physics step, plant monitor, CSV row)")
    print(f"  the floor of that ratio, (controller + the job's physics step {step_us:.0f} us) / controller : "
          f"{(ctrl_us + step_us) / ctrl_us:.2f}")
    print_job_overhead(rows)


def scaling(robot) -> None:
    """Cycle time against the number of contact points per foot."""
    states = _states(robot, n=30)
    q0 = crouched_start(robot)
    print("WBC cycle against contact points per foot (the same squat states):")
    for n in (4, 8, 16):
        ctrl = _controller(robot, q0, points_per_foot=n)
        t = _per_cycle(ctrl.compute, states, repeats=3)
        print(f"  {n:2d} points per foot ({ctrl.n_x} variables): {t * 1e6:6.0f} us")


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
                          Path("out/bench_push") / f"{angle}", quiet=True)
            # survived: did not fall and the feet held (a sideways shove can slide the robot
            # across the floor without a fall: that is not standing the push)
            held = rec.values.get("fell") is False and rec.values["max_foot_slip_m"] < MAX_SLIP_M
            lo, hi = (mid, hi) if held else (lo, mid)
        print(f"  direction {angle:3d} deg: {lo:5.1f} N s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--push", action="store_true", help="Also bisect the largest push per direction.")
    parser.add_argument("--section", choices=("all", "job"), default="all",
                        help="job: only the g1-wbc job's cycle overhead (3 runs of the 4 s squat).")
    args = parser.parse_args()
    if args.section == "job":
        print_job_overhead(job_overhead())
        return
    robot = position_to_motor(with_palm_sites(load_robot("g1")))
    figures = timings(robot)
    job_ratios(robot, figures["bench_controller_us"])
    scaling(robot)
    if args.push:
        push_limits()


if __name__ == "__main__":
    main()
