"""Plan a Cartesian square, turn it into joint motion, and track it with computed torque.

Pipeline, all on the public API:

1. ``square_path``: a 0.2 m square in the arm's plane (x-y), sharp corners.
2. ``time_path``: a jerk-limited ruckig timing law on the arc length, at rest at every corner.
3. ``to_joint_trajectory``: joint positions from the analytic 2-link IK (``TwoLinkArm``, one
   elbow branch), velocities and accelerations through the Jacobian.
4. ``ComputedTorque``: ``tau = M(q) (a_ref + kp e + kd de) + b(q, v)`` from the Pinocchio model,
   run by ``mbctl.control.run`` on the MuJoCo plant with gravity on.

The Cartesian error is measured in MuJoCo: the end-effector site position from MuJoCo's own
kinematics (``mj_kinematics`` on a scratch ``MjData``) at each logged configuration, against the
planned position at the same time.

Run::

    python examples/03_computed_torque_square.py              # the whole square, ~2.8 s
    python examples/03_computed_torque_square.py --duration 0.3

Exits 1 if the RMS Cartesian error exceeds 1 mm.
"""

from __future__ import annotations

import argparse
import sys

import mujoco
import numpy as np

from mbctl.control import ComputedTorque, gains_from_frequency, run
from mbctl.control.ik import ElbowBranch, TwoLinkArm
from mbctl.planners import PathLimits, square_path, time_path, to_joint_trajectory
from mbctl.robots import load_robot
from mbctl.sim import Simulator

SITE = "end_effector"
CENTER_M = (0.30, 0.25, 0.0)  # square centre in the world frame (the arm's plane is z = 0)
SIDE_M = 0.2
LIMITS = PathLimits(max_speed=0.5, max_acceleration=3.0, max_jerk=40.0)  # m/s, m/s^2, m/s^3
OMEGA_RAD_S = 30.0  # closed-loop natural frequency of the error dynamics
ZETA = 1.0
SETTLE_S = 0.2  # time after the square [s], holding the last corner
MAX_RMS_ERROR_M = 1e-3


def main() -> int:
    """Plan, track, measure in MuJoCo; returns the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=None,
                        help="simulated time [s] (default: the whole square plus 0.2 s)")
    args = parser.parse_args()
    if args.duration is not None and not args.duration > 0:
        parser.error(f"--duration must be > 0 s; got {args.duration}")

    robot = load_robot("two_link_torque", gravity=True)
    sim = Simulator(robot)
    arm = TwoLinkArm.from_robot(robot, SITE)
    cartesian = time_path(square_path(CENTER_M, SIDE_M), LIMITS, sim.control_period_s)
    trajectory = to_joint_trajectory(
        cartesian,
        lambda p: arm.inverse_kinematics(p, ElbowBranch.DOWN),
        arm.jacobian,
        tuple(robot.joints),
        task_dims=2,
    )
    duration = args.duration or trajectory.duration_s + SETTLE_S
    print(f"square: side {SIDE_M} m around {CENTER_M[:2]} m, {len(cartesian.t_s)} samples over "
          f"{cartesian.duration_s:.3f} s, peak speed {cartesian.speed.max():.3f} m/s")

    controller = ComputedTorque(robot, gains_from_frequency(OMEGA_RAD_S, ZETA))
    sim.reset(q=trajectory.q[0])
    log = run(sim, controller, trajectory, duration)

    data = mujoco.MjData(robot.mj_model)
    site_id = robot.site_id(SITE)
    p_measured = np.empty((log.cycles, 3))
    for k, q in enumerate(log.q):
        data.qpos[:] = robot.converter.q_pin_to_mj(q)
        mujoco.mj_kinematics(robot.mj_model, data)
        p_measured[k] = data.site_xpos[site_id]
    # The planned sample at each cycle's time; after the square the reference holds its end.
    sample = np.rint((log.t_s - log.t_s[0]) / cartesian.dt_s).astype(int)
    sample = np.minimum(sample, len(cartesian.t_s) - 1)
    error = np.linalg.norm(cartesian.p[sample] - p_measured, axis=1)
    rms, worst = float(np.sqrt(np.mean(error**2))), float(np.max(error))
    saturated = controller.saturation.saturated_cycles
    print(f"computed torque (omega {OMEGA_RAD_S:g} rad/s, zeta {ZETA:g}), {log.cycles} cycles "
          f"over {duration:.3f} s, {saturated} saturated cycles")
    print(f"Cartesian error in MuJoCo: RMS {1e3 * rms:.4f} mm, max {1e3 * worst:.4f} mm "
          f"(bound RMS {1e3 * MAX_RMS_ERROR_M:g} mm)")
    return 0 if rms <= MAX_RMS_ERROR_M else 1


if __name__ == "__main__":
    sys.exit(main())
