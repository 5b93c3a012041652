"""Setup checks for the 2-link arm: the plant steps, commands move it, the end effector reads."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mbctl.jobs.choices import TWO_LINK_ROBOTS
from mbctl.robots.commands import position_target, torque
from mbctl.robots.exceptions import RobotError
from mbctl.robots.model_pair import Robot
from mbctl.robots.registry import load_robot
from mbctl.sim.simulator import Simulator

#: The robots these checks are written for (the 2-link arm, either actuation).
SUPPORTED = TWO_LINK_ROBOTS

#: A joint angle change [rad] below this counts as "no measurable motion".
MIN_MOTION_RAD = 1e-3


@dataclass(frozen=True)
class Check:
    """One setup check: its name, whether it passed, and what was measured."""

    name: str
    passed: bool
    detail: str


def verify_two_link(robot: Robot) -> list[Check]:
    """Run the 2-link setup checks.

    100 steps give 0.2 s; q has 2 elements; ctrl [5, -3] moves the joints; the end-effector site
    position is readable and matches the sensor.
    """
    sim = Simulator(robot)
    checks = []
    q0 = sim.q
    checks.append(Check("q has 2 elements", q0.shape == (2,), f"q shape {q0.shape}"))
    kinds = {a.kind for a in robot.actuators.values()}
    command = torque if kinds == {"torque"} else position_target
    sim.step(command([5.0, -3.0]), 100)
    t = sim.time_s
    checks.append(Check("100 steps give 0.2 s", abs(t - 0.2) < 1e-9, f"time {t:.12g} s"))
    dq = sim.q - q0
    checks.append(
        Check(
            "ctrl [5, -3] changes the joint angles",
            bool(np.all(np.abs(dq) > MIN_MOTION_RAD)),
            f"dq = [{dq[0]:+.4f}, {dq[1]:+.4f}] rad",
        )
    )
    p, _ = sim.site_pose("end_effector")
    ok = bool(np.all(np.isfinite(p)))
    if "ee_pos" in robot.sensors:
        ok = ok and bool(np.allclose(sim.sensor("ee_pos"), p, atol=1e-12))
    detail = f"p = [{p[0]:+.4f}, {p[1]:+.4f}, {p[2]:+.4f}] m"
    checks.append(Check("end-effector position readable", ok, detail))
    checks.append(Check("no MuJoCo warnings", not sim.warnings, f"warnings {sim.warnings or 'none'}"))
    return checks


def verify_robot(name: str) -> list[Check]:
    """Load robot ``name`` and run its setup checks.

    Raises:
        RobotError: ``name`` is not one of ``SUPPORTED`` (the checks are the 2-link arm's).
    """
    if name not in SUPPORTED:
        raise RobotError(
            f"verify runs the 2-link arm's setup checks; {name!r} is not supported (choose "
            f"{' or '.join(SUPPORTED)}; for any robot, `mbctl xcheck ROBOT` checks its model)"
        )
    return verify_two_link(load_robot(name))
