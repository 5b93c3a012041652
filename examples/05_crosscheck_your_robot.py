"""Cross-check your own robot: Pinocchio's dynamics against MuJoCo's, from one MJCF file.

Without arguments the script writes a small robot in code to a temporary directory and checks
it: a 3-link arm hanging from a rotated root body, with a ball shoulder, a hinge elbow and a
slide joint that extends the forearm, joint damping and armature, a full (off-diagonal) inertia,
and a tool site whose size and colour come from a default class. ``load_robot(path)`` builds
both engines' models from that file and checks they describe the same mechanism;
``crosscheck`` then compares forward kinematics, Jacobians, the mass matrix, gravity and bias
forces, forward and inverse dynamics, energies and momentum over random and edge states, and
prints a report that says what was compared, what was left out and why.

Afterwards the robot is simulated passively (zero controls) for ``--duration`` seconds and the
final pose of every site (or, without sites, every body) is compared between the two engines.

Run::

    python examples/05_crosscheck_your_robot.py
    python examples/05_crosscheck_your_robot.py --robot my_robot.xml --scene my_scene.xml
    python examples/05_crosscheck_your_robot.py --duration 0.1 --states 20

Exits 1 if the cross-check fails or the final poses differ by more than 1 nm; exits 2 if the
robot file cannot be loaded (the message says why).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

from mbctl.robots import Robot, RobotError, load_robot
from mbctl.robots.crosscheck import crosscheck
from mbctl.sim import Simulator

#: The example robot. Lengths [m], masses [kg], inertias [kg m^2], angles [rad].
THREE_LINK_ARM_MJCF = """\
<mujoco model="three_link_arm">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="0.002" gravity="0 0 -9.81"/>
  <default>
    <joint damping="0.05" armature="0.01"/>
    <geom type="capsule" size="0.03" contype="0" conaffinity="0"/>
    <default class="tool">
      <site size="0.015" rgba="1 0 0 1"/>
    </default>
  </default>
  <worldbody>
    <body name="base" pos="0.1 -0.2 0.5" euler="0.3 0 0.5">
      <joint name="shoulder" type="ball"/>
      <geom fromto="0 0 0 0 0 -0.3"/>
      <inertial pos="0 0 -0.15" mass="1.2" diaginertia="0.01 0.01 0.002"/>
      <body name="upper" pos="0 0 -0.3" quat="0.9238795 0 0.3826834 0">
        <joint name="elbow" type="hinge" axis="0 1 0" range="-2 2"/>
        <geom fromto="0 0 0 0 0 -0.25"/>
        <inertial pos="0 0 -0.12" mass="0.8" diaginertia="0.005 0.004 0.001"/>
        <body name="forearm" pos="0 0 -0.25">
          <joint name="extend" type="slide" axis="0 0 -1" range="0 0.1"/>
          <geom fromto="0 0 0 0 0 -0.15" size="0.02"/>
          <inertial pos="0.01 0 -0.07" mass="0.4" fullinertia="0.002 0.0021 0.0005 0.0001 0 0"/>
          <site name="tool" class="tool" pos="0 0 -0.15"/>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor name="elbow" joint="elbow" ctrlrange="-10 10"/>
    <motor name="extend" joint="extend" ctrlrange="-50 50"/>
  </actuator>
</mujoco>
"""
MAX_POSE_DIFFERENCE_M = 1e-9


def final_pose_difference(robot: Robot, duration_s: float) -> float:
    """Simulate passively for ``duration_s`` [s]; largest site (or body) position difference [m]."""
    sim = Simulator(robot)
    sim.step(n=max(1, round(duration_s / robot.timestep_s)))
    names = list(robot.sites) or list(robot.bodies)
    pose = sim.site_pose if robot.sites else sim.body_pose
    q = sim.q
    worst, worst_name = 0.0, ""
    for name in names:
        p_mujoco, _ = pose(name)
        p_pinocchio, _ = robot.frame_pose(name, q)
        difference = float(np.linalg.norm(p_mujoco - p_pinocchio))
        if difference >= worst:
            worst, worst_name = difference, name
    kind = "site(s)" if robot.sites else "bodies"
    print(f"passive run: {sim.n_steps} steps ({sim.time_s:.3f} s) at zero controls, MuJoCo "
          f"warnings: {sim.warnings or 'none'}")
    print(f"final pose, {len(names)} {kind}: largest Pinocchio - MuJoCo position difference "
          f"{worst:.3e} m at {worst_name!r} (bound {MAX_POSE_DIFFERENCE_M:g} m)")
    return worst


def check(robot_file: Path, scene_file: Path | None, n_states: int, duration_s: float) -> int:
    """Load, cross-check and simulate one robot; returns the exit code."""
    try:
        robot = load_robot(robot_file, scene_file)
    except RobotError as exc:
        print(f"cannot load {robot_file}: {exc}", file=sys.stderr)
        return 2
    joints = [f"{j.name} ({j.kind})" for j in robot.joints.values()]
    print(f"{robot}: {len(joints)} joints: {', '.join(joints[:6])}{' ...' if len(joints) > 6 else ''}")
    report = crosscheck(robot, n_states=n_states)
    print(report.to_text())
    difference = final_pose_difference(robot, duration_s)
    return 0 if report.passed and difference <= MAX_POSE_DIFFERENCE_M else 1


def main() -> int:
    """Check the robot built in code, or the user's file; returns the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=1.0, help="passive simulation [s]")
    parser.add_argument("--states", type=int, default=100, help="random states to compare")
    parser.add_argument("--robot", type=Path, default=None,
                        help="your MJCF robot file (default: the 3-link arm built in code)")
    parser.add_argument("--scene", type=Path, default=None,
                        help="a scene file for MuJoCo that includes --robot")
    args = parser.parse_args()
    if not args.duration > 0:
        parser.error(f"--duration must be > 0 s; got {args.duration}")
    if args.states < 0:
        parser.error(f"--states must be >= 0; got {args.states}")
    if args.scene is not None and args.robot is None:
        parser.error("--scene needs --robot")
    if args.robot is not None:
        return check(args.robot, args.scene, args.states, args.duration)
    with tempfile.TemporaryDirectory() as folder:
        robot_file = Path(folder) / "three_link_arm.xml"
        robot_file.write_text(THREE_LINK_ARM_MJCF)
        return check(robot_file, None, args.states, args.duration)


if __name__ == "__main__":
    sys.exit(main())
