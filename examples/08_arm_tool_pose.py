"""Move a fixed-base arm's tool to a pose: IK, a ruckig trajectory, computed torque, checked in MuJoCo.

Any fixed-base arm with its scene: the default is a 6-dof arm shipped beside this file
(``assets/arm6.xml``, on a table in ``assets/arm6_scene.xml``); ``--robot PATH --scene PATH``
runs yours (every dof actuated; position actuators are converted to torque motors, as the
computed-torque law needs, and the run says so). Pipeline, all on the public API:

1. IK on a tool pose: a ``FramePoseTask`` on the tool frame (position and orientation; the
   target is the start pose moved by ``--offset`` metres in the world and turned by ``--yaw``
   degrees about the world z axis), a small ``PostureTask``, joint position limits, solved by
   ``DiffIK`` (the QP on Pinocchio Jacobians) to 0.1 mm and 1 mrad; the result is then checked
   with MuJoCo's own kinematics (``mj_kinematics`` on a scratch ``MjData``).
2. ``plan_ruckig``: a jerk-limited, time-synchronised joint trajectory from the start to the
   IK solution, under ``JointLimits`` (velocity, acceleration, jerk per joint).
3. ``ComputedTorque`` tracks it on the MuJoCo plant (gravity on), run by ``mbctl.control.run``;
   the tool's position is measured in MuJoCo along the run against the planned one, and its
   final pose against the target.

Run::

    python examples/08_arm_tool_pose.py
    python examples/08_arm_tool_pose.py --robot my_arm.xml --scene my_scene.xml --tool gripper_site
    python examples/08_arm_tool_pose.py --duration 0.1

Exits 2 on bad input (a file, frame or keyframe that does not exist; an arm that computed torque
cannot drive), 1 if the IK does not converge, the IK pose misses the target in MuJoCo by more
than 1 mm, or (with the whole trajectory run) the tool ends more than 1 mm from the target.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin

from mbctl.control import ComputedTorque, gains_from_frequency, run
from mbctl.control.ik import DiffIK, JointPositionLimit
from mbctl.control.tasks import FramePoseTask, KinematicState, PostureTask, Tolerance
from mbctl.exceptions import ToolkitError
from mbctl.planners import JointLimits, plan_ruckig
from mbctl.robots import load_robot, position_to_motor
from mbctl.sim import Simulator

ASSETS = Path(__file__).resolve().parent / "assets"
IK_TOLERANCE = Tolerance(position_m=1e-4, orientation_rad=1e-3)
MAX_POSE_ERROR_M = 1e-3
LIMITS = dict(max_velocity=1.0, max_acceleration=3.0, max_jerk=30.0)  # rad/s, rad/s^2, rad/s^3
OMEGA_RAD_S, ZETA = 30.0, 1.0  # closed-loop natural frequency and damping of the joint errors
SETTLE_S = 0.3  # held at the goal after the trajectory [s]


def tool_pose_in_mujoco(robot, data: mujoco.MjData, tool: str, q: np.ndarray) -> pin.SE3:
    """The tool's pose X_WT from MuJoCo's kinematics at ``q`` (Pinocchio convention)."""
    robot.plant_qpos(q, data.qpos)
    mujoco.mj_kinematics(robot.mj_model, data)
    if tool in robot.sites:
        site = robot.site_id(tool)
        return pin.SE3(data.site_xmat[site].reshape(3, 3).copy(), data.site_xpos[site].copy())
    body = robot.mj_model.body(tool).id
    return pin.SE3(data.xmat[body].reshape(3, 3).copy(), data.xpos[body].copy())


def main() -> int:
    """IK, plan, track, measure in MuJoCo; returns the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default=str(ASSETS / "arm6.xml"), help="the arm's MJCF file")
    parser.add_argument("--scene", default=None,
                        help="a scene that includes the robot file (default: arm6_scene.xml for the "
                             "shipped arm, else the robot file alone)")
    parser.add_argument("--tool", default="tool", help="the tool frame: a site or body of the arm")
    parser.add_argument("--keyframe", default="home",
                        help="start configuration (a keyframe of the model; 'none' for qpos0)")
    parser.add_argument("--offset", default="-0.1,0.2,-0.15",
                        help="tool displacement X,Y,Z [m] in the world frame")
    parser.add_argument("--yaw", type=float, default=30.0, help="tool rotation about world z [deg]")
    parser.add_argument("--duration", type=float, default=None,
                        help="simulated time [s] (default: the trajectory plus 0.3 s)")
    args = parser.parse_args()
    try:
        offset = np.array([float(x) for x in args.offset.split(",")])
        if offset.shape != (3,):
            raise ValueError
    except ValueError:
        parser.error(f"--offset must be three numbers X,Y,Z [m]; got {args.offset!r}")
    if args.duration is not None and not args.duration > 0:
        parser.error(f"--duration must be > 0 s; got {args.duration}")
    scene = args.scene or (str(ASSETS / "arm6_scene.xml") if Path(args.robot).resolve() == ASSETS / "arm6.xml"
                           else None)
    try:
        robot = load_robot(args.robot, scene)
        if robot.has_floating_base:
            raise ToolkitError(f"{robot.name!r} has a floating base; this example is for fixed-base arms")
        if any(a.kind != "torque" for a in robot.actuators.values()):
            robot = position_to_motor(robot)
            print(f"converted to torque motors: {'; '.join(robot.source.edits)}")
        q0 = robot.neutral_q() if args.keyframe == "none" else robot.keyframe_q(args.keyframe)
        state = KinematicState(robot.pin_model)  # raises UnknownNameError for an unknown --tool:
        tool_task = FramePoseTask(args.tool, state, position_cost=1.0, orientation_cost=0.5, lm_damping=1e-3)

        # 1. IK on the tool pose: position and orientation, limits, a light posture regulariser
        data = mujoco.MjData(robot.mj_model)
        start = tool_pose_in_mujoco(robot, data, args.tool, q0)
        target = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, np.radians(args.yaw)) @ start.rotation,
                         start.translation + offset)
        tool_task.set_target(target)
        posture = PostureTask(state, cost=1e-3)
        posture.set_target(q0)
        ik = DiffIK(robot.pin_model, [tool_task, posture], [JointPositionLimit(robot.pin_model)])
        result = ik.solve(q0, tolerance=IK_TOLERANCE, max_iters=200)
        controller = ComputedTorque(robot, gains_from_frequency(OMEGA_RAD_S, ZETA))
    except ToolkitError as exc:  # a bad file, frame, keyframe, or an arm this law cannot drive
        print(f"error: {exc}", file=sys.stderr)
        return 2
    reached = tool_pose_in_mujoco(robot, data, args.tool, result.q)
    ik_error_m = float(np.linalg.norm(reached.translation - target.translation))
    ik_error_rad = float(np.linalg.norm(pin.log3(target.rotation.T @ reached.rotation)))
    print(f"{robot}: tool {args.tool!r} from {np.round(start.translation, 4).tolist()} m to "
          f"{np.round(target.translation, 4).tolist()} m, turned {args.yaw:g} deg about z")
    print(f"IK: converged {result.converged} in {result.iterations} iterations; in MuJoCo the tool is "
          f"{1e3 * ik_error_m:.4f} mm and {1e3 * ik_error_rad:.4f} mrad from the target")

    # 2. a jerk-limited joint trajectory to the IK solution
    joints = tuple(robot.joints)
    sim = Simulator(robot)
    limits = JointLimits.uniform(len(joints), **LIMITS)
    trajectory = plan_ruckig(q0, result.q, limits, sim.control_period_s, joints)
    print(f"ruckig: {trajectory.duration_s:.3f} s under {LIMITS}")

    # 3. computed torque on the plant, the tool measured in MuJoCo
    duration = args.duration or trajectory.duration_s + SETTLE_S
    sim.reset(q=q0)
    log = run(sim, controller, trajectory, duration)
    measured = np.array([tool_pose_in_mujoco(robot, data, args.tool, q).translation for q in log.q])
    q_planned = np.repeat(q0[None], len(log.reference), axis=0)
    q_planned[:, controller.joint_map.idx_q] = log.reference  # columns in the controller's joint order
    planned = np.array([tool_pose_in_mujoco(robot, data, args.tool, q).translation for q in q_planned])
    rms_m = float(np.sqrt(np.mean(np.sum((measured - planned) ** 2, axis=1))))
    final = tool_pose_in_mujoco(robot, data, args.tool, log.q[-1])
    final_m = float(np.linalg.norm(final.translation - target.translation))
    print(f"computed torque, {sim.time_s:.3f} s simulated: tool RMS {1e3 * rms_m:.4f} mm from the planned "
          f"path, final {1e3 * final_m:.4f} mm from the target (measured in MuJoCo); saturated cycles "
          f"{controller.saturation.saturated_cycles}, MuJoCo warnings {sim.warnings or 'none'}")
    whole = duration >= trajectory.duration_s
    ok = result.converged and ik_error_m <= MAX_POSE_ERROR_M and (not whole or final_m <= MAX_POSE_ERROR_M)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
