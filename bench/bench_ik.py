"""Per-iteration time of G1 whole-body IK: our Pinocchio QP vs mink, same tasks, solver, limits.

Sections (``--section``, default all), every ratio measured in the same run, timing blocks of the
two backends interleaved so machine load hits both alike:

* ``base``: mink's humanoid task set (both feet (pose), both palms (position), CoM (x, y), pelvis
  orientation, posture; limits: joint position, joint velocity, floating-base velocity). One
  "iteration" = update the kinematics at q, build the QP, solve it (daqp), integrate the step.
  Convergence: both palms moved 10 cm forward, iterate to 1 mm.
* ``collisions``: the same task set with the palms crossed (the issue's case) plus the G1's default
  self-collision set (96 geom pairs) as a collision-avoidance limit in both backends (the same geom
  pairs, detection 0.1 m, minimum 5 mm); consecutive iterations of a solve from the stand pose
  (ours: guard included, one distance query per pair per iteration). The cost of the pairs: the
  added time per pair and per detected pair against the same solve without the limit, and each
  pair's ``mj_geomDistance`` time (its median over the configurations where it was detected).
* ``scaling``: iteration time against the number of frame tasks (1 to 8 full-pose tasks on G1
  bodies and sites, plus posture), ours and mink.

Run: MENAGERIE_ROOT=... python bench/bench_ik.py [--repeats N] [--solver daqp] [--section base]
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import mujoco
import numpy as np
import pinocchio as pin

from mbctl.control.ik import MinkWholeBodyIK, QPWholeBodyIK, WholeBodyIKConfig
from mbctl.control.tasks import Tolerance
from mbctl.jobs.ik import g1_config
from mbctl.robots import load_robot
from mbctl.robots.collision import CollisionPair
from mbctl.robots.g1 import KEYFRAME, PALM_SITES, SELF_COLLISION_PAIRS, with_palm_sites

#: The issue's crossed palms [m], world frame.
CROSSED = {"left_palm": (0.28, -0.12, 0.95), "right_palm": (0.28, 0.12, 0.95)}

#: Frames of the scaling section, in the order they are added.
SCALING_FRAMES = ("left_palm", "right_palm", "left_foot", "right_foot", "torso_link", "pelvis",
                  "left_knee_link", "right_knee_link")


def _load() -> str:
    return " ".join(f"{x}" for x in os.getloadavg())


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


def base(robot, q0, args) -> None:
    """Mink's humanoid task set, palms +10 cm: per-iteration medians and the ratio."""
    offset = np.array([0.10, 0.0, 0.0])  # [m] both palms forward
    ours, theirs = _setup(robot, q0, args.solver, offset)
    q0_mj = robot.converter.q_pin_to_mj(q0)
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
    print(f"  ratio ours/mink    : {med_ours / med_mink:.3f}  (goal <= 0.30)")
    print("convergence, palms +10 cm in x, tol 1 mm:")
    print(
        f"  ours: {'converged' if res.converged else 'NOT converged'} in {res.iterations} "
        f"iterations, max palm error {palm_err * 1e3:.3f} mm"
    )
    print(
        f"  mink: {'converged' if mink_res.converged else 'NOT converged'} in "
        f"{mink_res.iterations} iterations, max palm error {mink_err * 1e3:.3f} mm"
    )


def _crossed(robot, q0, solver, backend, pairs):
    cfg = g1_config(collision_pairs=pairs)
    ik = backend(robot, cfg, q0, solver=solver)
    for palm, target in CROSSED.items():
        ik.set_target_position(palm, target)
    return ik


def _solve_times(ik, q0, n_iterations, repeats):
    """Per-iteration times [s] of ``repeats`` solves of ``n_iterations`` consecutive steps from ``q0``."""
    times = []
    for _ in range(repeats):
        ik.update(q0)
        for _ in range(n_iterations):
            t0 = time.perf_counter()
            ik.advance()
            times.append(time.perf_counter() - t0)
    return times


def collisions(robot, q0, args) -> None:
    """The crossed palms with and without the G1's self-collision set, both backends."""
    pairs = tuple(CollisionPair(a, b) for a, b in SELF_COLLISION_PAIRS)
    backends = (("ours", QPWholeBodyIK), ("mink", MinkWholeBodyIK))
    iks = {(name, with_pairs): _crossed(robot, q0, args.solver, cls, pairs if with_pairs else ())
           for name, cls in backends for with_pairs in (False, True)}
    n_pairs = len(iks["ours", True].collision_pairs)
    steps = 12
    for ik in iks.values():
        _solve_times(ik, q0, steps, 2)  # warm up
    samples: dict[tuple[str, bool], list[float]] = {key: [] for key in iks}
    blocks = max(args.repeats // 60, 3)
    for _ in range(blocks):
        for key, ik in iks.items():
            samples[key] += _solve_times(ik, q0, steps, 3)
    med = {key: statistics.median(v) for key, v in samples.items()}
    detected = _detected_per_iteration(iks["ours", True], q0, steps)
    print(f"G1 whole-body IK with collision avoidance, palms crossed, {n_pairs} geom pairs (the G1's default "
          f"self-collision set), detection 0.1 m, minimum 5 mm, solver={args.solver}, "
          f"{len(samples['ours', True])} iterations timed per backend")
    for name in ("ours", "mink"):
        added = med[name, True] - med[name, False]
        print(f"  {name:4s}: median {med[name, True] * 1e6:7.1f} us/iteration with the pairs, "
              f"{med[name, False] * 1e6:6.1f} without; +{added / n_pairs * 1e6:.2f} us per pair, "
              f"+{added / detected * 1e6:.1f} us per detected pair ({detected:.1f} detected per iteration)")
    print(f"  ratio ours/mink (with pairs)   : {med['ours', True] / med['mink', True]:.3f}  (goal <= 0.50)")
    _pair_costs(robot, iks["ours", True], q0, steps, args.verbose)


def _detected_per_iteration(ik, q0, steps) -> float:
    counts = []
    ik.update(q0)
    for _ in range(steps):
        ik.advance()
        counts.append(int(np.sum(ik.collision_limit.distances_m < ik.collision_limit.detection_distance_m)))
    return float(np.mean(counts))


def _pair_costs(robot, ik, q0, steps, verbose) -> None:
    """Each pair's mj_geomDistance time (median over the path's configurations where it is detected)."""
    limit = ik.collision_limit
    res = ik.solve(q0, max_iters=steps)
    m, data = robot.mj_model, mujoco.MjData(robot.mj_model)
    fromto = np.zeros(6)
    cost: dict[str, list[float]] = {}
    for q in res.q_path:
        robot.plant_qpos(q, data.qpos)
        mujoco.mj_kinematics(m, data)
        for (g1, g2), label in zip(limit.pairs.ids.tolist(), limit.pairs.labels, strict=True):
            t0 = time.perf_counter()
            d = mujoco.mj_geomDistance(m, data, g1, g2, limit.detection_distance_m, fromto)
            elapsed = time.perf_counter() - t0
            if d < limit.detection_distance_m:
                cost.setdefault(label, []).append(elapsed)
    ranked = sorted(((statistics.median(v), k, len(v)) for k, v in cost.items()), reverse=True)
    total = sum(c for c, _, _ in ranked)
    print(f"  per pair: {len(ranked)} of {len(limit.pairs)} pairs came within 0.1 m on our path; their "
          f"distance query (mj_geomDistance, one call each, median over the configurations): sum "
          f"{total * 1e6:.1f} us, median {statistics.median([c for c, _, _ in ranked]) * 1e6:.2f} us")
    for c, label, n in ranked if verbose else ranked[:8]:
        print(f"    {label:46s} {c * 1e6:6.2f} us  (detected at {n} of {len(res.q_path)} configurations)")


def scaling(robot, q0, args) -> None:
    """Iteration time against the number of frame tasks, ours and mink, as a markdown table."""
    print("| frame tasks | ours [us] | mink [us] | ours/mink |")
    print("| --- | --- | --- | --- |")
    rng = np.random.default_rng(0)
    for n in range(1, len(SCALING_FRAMES) + 1):
        cfg = WholeBodyIKConfig(held_frames=SCALING_FRAMES[:n], target_orientation_cost=1.0)
        ours = QPWholeBodyIK(robot, cfg, q0, solver=args.solver)
        theirs = MinkWholeBodyIK(robot, cfg, q0, solver=args.solver)
        q = pin.integrate(robot.pin_model, q0, 0.05 * rng.standard_normal(robot.nv))  # every task off target
        samples: dict[str, list[float]] = {"ours": [], "mink": []}
        for _ in range(max(args.repeats // 30, 5)):
            for name, ik in (("ours", ours), ("mink", theirs)):
                samples[name] += _solve_times(ik, q, 4, 3)
        o, k = statistics.median(samples["ours"]), statistics.median(samples["mink"])
        print(f"| {n} | {o * 1e6:.1f} | {k * 1e6:.1f} | {o / k:.2f} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=300, help="solves timed per solver (base section)")
    parser.add_argument("--solver", default="daqp")
    parser.add_argument("--section", choices=("all", "base", "collisions", "scaling"), default="all")
    parser.add_argument("--verbose", action="store_true", help="every detected pair's cost")
    args = parser.parse_args()

    robot = with_palm_sites(load_robot("g1"))
    q0 = robot.keyframe_q(KEYFRAME)
    print(f"load average before: {_load()}")
    for name, section in (("base", base), ("collisions", collisions), ("scaling", scaling)):
        if args.section in ("all", name):
            section(robot, q0, args)
    print(f"load average after: {_load()}")


if __name__ == "__main__":
    main()
