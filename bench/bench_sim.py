"""Simulator.step against a raw mj_step loop, on the G1 and the 2-link arm.

Run: MENAGERIE_ROOT=../shared/menagerie python bench/bench_sim.py
Prints per-step medians [us] and the ratio API / raw, both measured in this run.
"""

from __future__ import annotations

import sys
from pathlib import Path

import mujoco
import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from harness import interleaved  # noqa: E402

from mbctl.robots import load_robot  # noqa: E402
from mbctl.sim import Simulator, position_target, torque  # noqa: E402

STEPS = 2000


def case(name: str, robot, make_command, keyframe=None) -> list[tuple[str, float, float]]:
    sim = Simulator(robot)
    m = robot.mj_model
    d = mujoco.MjData(m)
    rng = np.random.default_rng(0)

    def reset():
        sim.reset(keyframe)
        if keyframe is None:
            mujoco.mj_resetData(m, d)
        else:
            mujoco.mj_resetDataKeyframe(m, d, robot.keyframe_id(keyframe))

    base = np.array(sim.ctrl if keyframe else np.zeros(m.nu))
    wiggle = base + 1e-3 * rng.standard_normal((STEPS, m.nu))
    held = make_command(base)
    commands = [make_command(u) for u in wiggle]

    def raw_held():
        reset()
        d.ctrl[:] = base
        for _ in range(STEPS):
            mujoco.mj_step(m, d)

    def api_held():
        reset()
        for _ in range(STEPS):
            sim.step(held)

    def raw_new():
        reset()
        for k in range(STEPS):
            d.ctrl[:] = wiggle[k]
            mujoco.mj_step(m, d)

    def api_new():
        reset()
        for k in range(STEPS):
            sim.step(make_command(wiggle[k]))

    def api_prebuilt():
        reset()
        for k in range(STEPS):
            sim.step(commands[k])

    t = interleaved(
        {"raw_held": raw_held, "api_held": api_held, "raw_new": raw_new, "api_new": api_new,
         "api_prebuilt": api_prebuilt}
    )
    us = {k: v / STEPS * 1e6 for k, v in t.items()}
    return [
        (f"{name}: same command every step", us["api_held"], us["raw_held"]),
        (f"{name}: new command built every step", us["api_new"], us["raw_new"]),
        (f"{name}: new prebuilt command every step", us["api_prebuilt"], us["raw_new"]),
    ]


def main() -> None:
    rows = []
    rows += case("2-link", load_robot("two_link_torque"), torque)
    g1 = load_robot("g1")
    rows += case("G1", g1, position_target, keyframe="stand")
    print(f"Simulator.step vs raw mj_step, {STEPS} steps, median of 9 interleaved runs")
    print(f"{'case':44s} {'API [us/step]':>14s} {'raw [us/step]':>14s} {'ratio':>7s}")
    for label, api, raw in rows:
        print(f"{label:44s} {api:14.2f} {raw:14.2f} {api / raw:7.2f}x")
    print("targets: G1 <= 1.15x, 2-link <= 2x")


if __name__ == "__main__":
    main()
