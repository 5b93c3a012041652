"""Per-iteration time of G1 whole-body IK: our Pinocchio QP vs mink, same tasks, solver, limits.

Task set (mink's humanoid example): both feet (pose), both palms (position), CoM (x, y),
pelvis orientation, posture; limits: joint position, joint velocity, floating-base velocity,
built once. One "iteration" = update the kinematics at q, build the QP, solve it (daqp),
integrate the step. Convergence: both palms moved 10 cm forward, iterate to 1 mm.

Run: MENAGERIE_ROOT=... python bench/bench_ik.py [--repeats N] [--solver daqp]
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
import pinocchio as pin

from mbctl.control.ik import MinkWholeBodyIK, QPWholeBodyIK
from mbctl.control.tasks import Tolerance
from mbctl.jobs.ik import g1_config
from mbctl.robots import load_robot
from mbctl.robots.g1 import KEYFRAME, PALM_SITES, with_palm_sites


def _setup(robot, q0, solver, offset):
    ours = QPWholeBodyIK(robot, g1_config(), q0, solver=solver)
    theirs = MinkWholeBodyIK(robot, g1_config(), q0, solver=solver)
    for palm in PALM_SITES:
        target = ours.frame_position(palm) + offset
        ours.set_target_position(palm, target)
        theirs.set_target_position(palm, target)
    return ours, theirs


def _time_ours(ours, q0, n, qp_times=None):
    times = []
    ik = ours.ik
    dt = ours.config.dt
    model = ik.model
    for _ in range(n):
        q = q0
        for _ in range(4):  # the first iterations of a solve: realistic active sets
            t0 = time.perf_counter()
            ik.update(q)
            step = ik.solve_step(dt)
            q = pin.integrate(model, q, step.dq)
            times.append(time.perf_counter() - t0)
            if qp_times is not None:
                qp_times.append(step.solve_time_s)
    return times


def _time_mink(theirs, q0_mj, n):
    times = []
    conf = theirs.configuration
    dt = theirs.config.dt
    for _ in range(n):
        conf.update(q0_mj)
        for _ in range(4):
            t0 = time.perf_counter()
            v = theirs.step_mj()
            conf.integrate_inplace(v, dt)  # integrates and updates the kinematics
            times.append(time.perf_counter() - t0)
    return times


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=300, help="solves timed per solver")
    parser.add_argument("--solver", default="daqp")
    args = parser.parse_args()

    robot = with_palm_sites(load_robot("g1"))
    q0 = robot.keyframe_q(KEYFRAME)
    offset = np.array([0.10, 0.0, 0.0])  # [m] both palms forward
    ours, theirs = _setup(robot, q0, args.solver, offset)
    q0_mj = robot.converter.q_pin_to_mj(q0)

    # warm up both, then interleave the timing blocks so machine load hits both alike
    _time_ours(ours, q0, 10)
    _time_mink(theirs, q0_mj, 10)
    t_ours: list[float] = []
    t_mink: list[float] = []
    t_qp: list[float] = []
    blocks = 10
    for _ in range(blocks):
        t_ours += _time_ours(ours, q0, args.repeats // blocks, t_qp)
        t_mink += _time_mink(theirs, q0_mj, args.repeats // blocks)
    med_ours = statistics.median(t_ours)
    med_mink = statistics.median(t_mink)

    res = ours.solve(q0, Tolerance(1e-3), max_iters=20)
    mink_res = theirs.solve(q0, Tolerance(1e-3), max_iters=20)
    palm_err = max(res.residuals[p].position_m for p in PALM_SITES)
    mink_err = max(mink_res.residuals[p].position_m for p in PALM_SITES)

    print(f"G1 whole-body IK, solver={args.solver}, {len(t_ours)} iterations timed per solver")
    print(
        f"  ours (Pinocchio QP): median {med_ours * 1e6:8.1f} us/iteration "
        f"(of which daqp itself {statistics.median(t_qp) * 1e6:.1f} us)"
    )
    print(f"  mink               : median {med_mink * 1e6:8.1f} us/iteration")
    print(f"  ratio ours/mink    : {med_ours / med_mink:.3f}  (goal <= 0.5)")
    print("convergence, palms +10 cm in x, tol 1 mm:")
    print(
        f"  ours: {'converged' if res.converged else 'NOT converged'} in {res.iterations} "
        f"iterations, max palm error {palm_err * 1e3:.3f} mm"
    )
    print(
        f"  mink: {'converged' if mink_res.converged else 'NOT converged'} in "
        f"{mink_res.iterations} iterations, max palm error {mink_err * 1e3:.3f} mm"
    )


if __name__ == "__main__":
    main()
