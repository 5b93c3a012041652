"""Load the 2-link arm, look up joints and actuators by name, and step the simulator.

The arm has position actuators (MuJoCo's internal PD), so a command is a position target
[rad] per actuator. After stepping, the end-effector site position is read twice: from MuJoCo
(the plant, via the simulator) and from Pinocchio (the analytic model) at the same joint angles;
both come from one MJCF file, so they agree to round-off.

Run::

    python examples/01_load_and_step.py               # 2 s of simulated time
    python examples/01_load_and_step.py --duration 0.1

Exits 1 if the two engines disagree on the site position by more than 1 nm.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from mbctl.robots import load_robot
from mbctl.sim import Simulator, position_target

SITE = "end_effector"
#: Position targets [rad] per actuator name.
TARGET_RAD = {"shoulder": 0.5, "elbow": -0.8}
#: Largest allowed difference [m] between the site positions of the two engines.
MAX_ENGINE_DIFFERENCE_M = 1e-9


def main() -> int:
    """Load, inspect, step, compare; returns the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=2.0, help="simulated time [s]")
    args = parser.parse_args()

    robot = load_robot("two_link")
    print(f"{robot}: {robot.source.origin}")
    for name, joint in robot.joints.items():
        print(f"  joint {name!r}: {joint.kind}, q[{joint.idx_q}], v[{joint.idx_v}]")
    for name, actuator in robot.actuators.items():
        low, high = actuator.ctrl_range
        print(f"  actuator {name!r}: {actuator.kind} on joint {actuator.joint!r}, "
              f"kp {actuator.kp:g} N m/rad, ctrl range [{low:g}, {high:g}] rad")
    print(f"  sites {list(robot.sites)}, sensors {list(robot.sensors)}")

    sim = Simulator(robot)
    steps = max(1, round(args.duration / robot.timestep_s))
    sim.step(position_target(TARGET_RAD), n=steps)
    q = sim.q
    print(f"after {sim.n_steps} steps ({sim.time_s:.3f} s):")
    for name, target in TARGET_RAD.items():
        actual = float(sim.joint_q(robot.actuator(name).joint)[0])
        print(f"  {name}: target {target:+.4f} rad, q {actual:+.4f} rad "
              f"(error {1e3 * (target - actual):+.3f} mrad)")
    print(f"  sensor ee_pos: {(np.round(sim.sensor('ee_pos'), 5) + 0.0).tolist()} m")

    p_mujoco, _ = sim.site_pose(SITE)
    p_pinocchio, _ = robot.frame_pose(SITE, q)
    difference = float(np.linalg.norm(p_mujoco - p_pinocchio))
    print(f"site {SITE!r}: MuJoCo {(np.round(p_mujoco, 6) + 0.0).tolist()} m, "
          f"Pinocchio {(np.round(p_pinocchio, 6) + 0.0).tolist()} m")
    print(f"engine difference: {difference:.3e} m (bound {MAX_ENGINE_DIFFERENCE_M:g} m)")
    return 0 if difference <= MAX_ENGINE_DIFFERENCE_M else 1


if __name__ == "__main__":
    sys.exit(main())
