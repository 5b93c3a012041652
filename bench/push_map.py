"""What held a pushed G1 walker's recovery: the first steps after each push and their limits (issue 28).

    MENAGERIE_ROOT=... python bench/push_map.py --impulse 48 --hold 0.08            # the 24 cases
    MENAGERIE_ROOT=... python bench/push_map.py --bisect 10,48 --hold 0.08 --phases early

Not a timing: each case is ``mbctl g1-walk push --speed 0.3 --impulse I --push-hold H --direction D
--push-phase P --duration 6.5 --gait G`` (``--gait``, default normal: the gait docs/api/walking.rst's
48 N s figures are of) run in-process (the job itself, its walker probed cycle by cycle).
For each case: ``survived`` (the job's), the touchdowns between the push and the fall (or the
first four), and for each step its footstep from the stance foot (forward, and outward from the
stance foot's side, in the world: the walk heads +x), its swing time, and the limit the step
adaptation held it at (``limited``): the forward or backward reach, the pushed outward reach, the
narrowest width (a footstep across the stance foot's line: crossed), the reach polygon between
them; "timing floor" where the swing lasted no more than ``min_single_support_s`` + 10 ms. The
leg and arm joints' share of cycles at 98 % of the model's torque limit or more, from the push to
0.1 s before the fall (at most 1.5 s). ``--bisect LO,HI``: the largest impulse survived per case
instead, bisected to within 1 N s (a case near its edge may flip with rounding: the edge is
where this bisection found it).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from typing import Any

import mujoco
import numpy as np


def run_case(robot: Any, impulse: float, direction: float, phase: str, hold: float, folder: str,
             gait: str = "normal") -> dict:
    """One push, the job run in-process with its walker probed; the case's figures (see the module)."""
    import mbctl.jobs.g1_walk as walk
    from mbctl.jobs.runner import Job, run_job

    box: dict[str, Any] = {}
    rows: list[dict[str, Any]] = []
    make = walk.g1_walker

    def probed(*args: Any, **kwargs: Any) -> Any:
        walker = box["walker"] = make(*args, **kwargs)
        compute = walker.compute

        def cycle(state: Any, reference: Any = None) -> Any:
            command = compute(state, reference)
            s, gait = walker.status, walker.gait
            placed = gait.placed if gait is not None else {}
            rows.append(dict(t=s.time_s, stance=s.stance, adaptation=s.adaptation, event=s.event,
                             tau=np.array(command.values), dcm=s.dcm.copy(),
                             placed={f: x.position[:2].copy() for f, x in placed.items()},
                             swing=(s.footsteps[0].foot, s.footsteps[0].position[:2].copy()) if s.footsteps
                             else None))
            return command

        walker.compute = cycle
        return walker

    walk.g1_walker = probed
    try:
        params = walk.WalkParams("push", speed="0.3", duration=6.5, impulse=impulse, direction=direction,
                                 push_phase=phase, push_hold=hold, gait=gait)
        record = run_job(Job("g1-walk", lambda p: walk.prepare(p, robot)), params, folder, quiet=True)
    finally:
        walk.g1_walker = make
    return _figures(record.values, rows, box["walker"], robot)


def _figures(v: dict, rows: list[dict], walker: Any, robot: Any) -> dict:
    push = v["pushes"][0] if v["pushes"] else None
    out: dict[str, Any] = dict(survived=bool(push and push["survived"]), fall_time_s=v["fall_time_s"])
    if push is None:
        return out
    t0, lim, cfg = push["time_s"], walker.limits, walker.config
    after = [r for r in rows if r["t"] >= t0 - 1e-9]
    touchdowns = [r for r in after if r["event"] is not None and r["event"].kind == "touchdown"]
    lifts = [r for r in rows if r["event"] is not None and r["event"].kind == "lift-off"]
    steps = []
    for td in touchdowns[:4]:
        foot = td["event"].foot
        before = rows[rows.index(td) - 1]  # the swing's last cycle: its footstep, the stance foot
        stance = before["placed"][before["stance"]]
        swung = before["swing"]
        target = swung[1] if swung and swung[0] == foot else td["placed"][foot]
        d = target - stance
        side = 1.0 if foot == walker.feet[0] else -1.0
        fwd, outward = float(d[0]), float(d[1]) * side
        lifted = [r["t"] for r in lifts if r["event"].foot == foot and r["t"] <= td["t"]]
        swing_s = td["t"] - lifted[-1] if lifted else None
        held = []
        a = before["adaptation"]
        if a is not None and a.limited:
            widest = lim.nominal_width_m + cfg.pushed_outward_fraction * lim.max_outward_m
            held += ["forward reach"] * (fwd >= lim.max_forward_m - 2e-3)
            held += ["backward reach"] * (fwd <= -lim.max_backward_m + 2e-3)
            held += ["outward reach"] * (outward >= widest - 2e-3)
            narrowest = abs(outward) <= lim.min_width_m + 2e-3
            held += (["crossed"] if outward < 0 else ["narrowest width"]) * narrowest
            held = held or ["reach polygon"]
        if swing_s is not None and swing_s <= cfg.min_single_support_s + 0.01:
            held.append("timing floor")
        steps.append(dict(t_s=round(td["t"], 3), distance_m=round(float(np.hypot(*d)), 3),
                          forward_m=round(fwd, 3), outward_m=round(outward, 3),
                          swing_s=None if swing_s is None else round(swing_s, 3),
                          held_by=held))
    out["steps"] = steps
    end = min(t0 + 1.5, (v["fall_time_s"] or np.inf) - 0.1)
    tau = np.array([r["tau"] for r in after if r["t"] <= end] or [np.zeros(robot.mj_model.nu)])
    m = robot.mj_model
    at = np.abs(tau) >= 0.98 * m.actuator_ctrlrange[:, 1]
    name = lambda j: mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, j)  # noqa: E731
    out["at_torque_limit"] = {name(j): round(float(at[:, j].mean()), 3)
                              for j in range(m.nu) if at[:, j].any()}
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--impulse", type=float, default=48.0, help="[N s]")
    ap.add_argument("--hold", type=float, default=0.08, help="the push's hold [s]")
    ap.add_argument("--phases", default="early,late,double")
    ap.add_argument("--directions", default="0,45,90,135,180,225,270,315", help="[deg]")
    ap.add_argument("--bisect", default=None, help="LO,HI [N s]: the largest impulse survived instead")
    ap.add_argument("--json", default=None, help="write the figures here")
    ap.add_argument("--gait", choices=("normal", "quick"), default="normal", help="g1-walk's --gait")
    args = ap.parse_args(argv)
    from mbctl.robots.registry import load_robot

    robot = load_robot("g1")
    folder = tempfile.mkdtemp(prefix="push_map_")
    figures: dict[str, Any] = {}
    for phase in args.phases.split(","):
        for direction in (float(d) for d in args.directions.split(",")):
            key = f"{phase} {direction:g}"
            if args.bisect is None:
                figures[key] = run_case(robot, args.impulse, direction, phase, args.hold, folder, args.gait)
                f = figures[key]
                first = f.get("steps", [])[:1]
                print(f"{key}: {'survived' if f['survived'] else 'FELL'}; steps {len(f.get('steps', []))}; "
                      f"first {first[0] if first else 'none'}", flush=True)
            else:
                lo, hi = (float(x) for x in args.bisect.split(","))
                if run_case(robot, hi, direction, phase, args.hold, folder, args.gait)["survived"]:
                    lo = hi
                elif not run_case(robot, lo, direction, phase, args.hold, folder, args.gait)["survived"]:
                    lo, hi = 0.0, lo
                while hi - lo > 1.0 + 1e-9:
                    mid = round(0.5 * (lo + hi), 1)
                    survived = run_case(robot, mid, direction, phase, args.hold, folder,
                                        args.gait)["survived"]
                    lo, hi = (mid, hi) if survived else (lo, mid)
                figures[key] = dict(largest_survived_n_s=lo, smallest_fell_n_s=hi)
                print(f"{key}: survived {lo:g} N s, fell at {hi:g}", flush=True)
            if args.json:
                with open(args.json, "w") as f:
                    json.dump(figures, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
