"""Whole-body inverse kinematics on the G1: palms 10 cm forward, feet held, CoM over the feet.

The differential-IK QP (Pinocchio model) weighs one task per goal: both feet keep their pose,
both palms move 10 cm forward (+x in the world), the centre of mass stays over the midpoint of
the feet (x, y), the pelvis keeps its orientation, and a small posture task regularises the
rest, under joint position and velocity limits. The task set is generic
(``WholeBodyIKConfig`` names the frames); the G1's names come from ``mbctl.robots.g1``.
The G1 has no palm sites, so ``with_palm_sites`` adds them to both engines at load time
(``mbctl.robots.edits.add_site``, recorded in ``robot.source.edits``).

The solution is checked independently in MuJoCo: the configuration is converted to MuJoCo's
convention (``robot.converter.q_pin_to_mj``), ``mj_kinematics`` and ``mj_comPos`` run on a
scratch ``MjData``, and the palm, foot and CoM positions are compared with their targets.

Then the solved joint angles are sent to the simulated robot standing on the floor as position
targets, ramped from the keyframe's over the first half of ``--duration`` seconds, and the palm
positions are measured on the plant at the end (the servos sag a few mm under the arms' weight).

Run::

    MENAGERIE_ROOT=/path/to/mujoco_menagerie python examples/06_g1_whole_body_ik.py
    python examples/06_g1_whole_body_ik.py --duration 0.1 --model-dir /path/to/unitree_g1

Exits 2 (with the loader's message) if the G1 model is not on this machine or its folder lacks
a file, and 1 if the IK does not converge, a residual measured in MuJoCo exceeds 1 mm, or the
simulated robot's pelvis drops below 0.7 m.
"""

from __future__ import annotations

import argparse
import sys

import mujoco
import numpy as np

from mbctl.control.ik import QPWholeBodyIK, WholeBodyIKConfig
from mbctl.control.tasks import Tolerance
from mbctl.robots import ModelFileError, ModelNotFoundError, load_robot
from mbctl.robots.g1 import FEET, KEYFRAME, PALM_SITES, PELVIS, with_palm_sites
from mbctl.sim import Simulator, position_target

PALMS = tuple(PALM_SITES)
PALM_OFFSET_M = np.array([0.1, 0.0, 0.0])  # in the world frame
IK_TOLERANCE_M = 1e-4
MAX_IK_ITERATIONS = 20
MAX_RESIDUAL_M = 1e-3
MIN_PELVIS_HEIGHT_M = 0.7  # the keyframe stands at 0.79 m


def main() -> int:
    """Solve, check in MuJoCo, simulate; returns the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=1.0,
                        help="simulated time [s] holding the solved pose")
    parser.add_argument("--model-dir", default=None, help="Menagerie unitree_g1 directory")
    args = parser.parse_args()
    if not args.duration > 0:
        parser.error(f"--duration must be > 0 s; got {args.duration}")
    try:
        robot = with_palm_sites(load_robot("g1", model_dir=args.model_dir))
    except (ModelNotFoundError, ModelFileError) as exc:  # not on this machine, or incomplete
        print(exc, file=sys.stderr)
        return 2
    print(f"{robot}: {robot.source.origin}; edits: {'; '.join(robot.source.edits)}")

    # Scratch MuJoCo data for the checks: kinematics only, the simulator is not involved.
    data = mujoco.MjData(robot.mj_model)

    def positions_in_mujoco(q: np.ndarray) -> tuple[dict[str, np.ndarray], np.ndarray]:
        """Site positions p_WS (3,) [m] by name and the CoM p_WC (3,) [m] at ``q`` (Pinocchio)."""
        data.qpos[:] = robot.converter.q_pin_to_mj(q)
        mujoco.mj_kinematics(robot.mj_model, data)
        mujoco.mj_comPos(robot.mj_model, data)
        sites = {name: data.site_xpos[robot.site_id(name)].copy() for name in (*PALMS, *FEET)}
        return sites, data.subtree_com[0].copy()

    q0 = robot.keyframe_q(KEYFRAME)
    start, _ = positions_in_mujoco(q0)
    targets = {palm: start[palm] + PALM_OFFSET_M for palm in PALMS}
    targets.update({foot: start[foot] for foot in FEET})
    com_xy = 0.5 * (start["left_foot"][:2] + start["right_foot"][:2])

    # feet held, palm position targets, CoM over the feet, pelvis orientation, posture
    config = WholeBodyIKConfig(held_frames=FEET, target_frames=tuple(PALM_SITES), base_frame=PELVIS, com=True)
    ik = QPWholeBodyIK(robot, config, q0)
    for palm in PALMS:
        ik.set_target_position(palm, targets[palm])
    ik.set_com_target(com_xy)
    result = ik.solve(q0, Tolerance(IK_TOLERANCE_M, 10 * IK_TOLERANCE_M), max_iters=MAX_IK_ITERATIONS)
    print(f"IK: converged {result.converged} in {result.iterations} iterations, "
          f"{1e3 * result.wall_time_s:.1f} ms")

    sites, com = positions_in_mujoco(result.q)
    worst = 0.0
    for name in (*PALMS, *FEET):
        residual = float(np.linalg.norm(sites[name] - targets[name]))
        worst = max(worst, residual)
        own = 1e3 * (result.residuals[name].position_m or 0.0)
        print(f"  {name}: target {(np.round(targets[name], 4) + 0.0).tolist()} m, residual in MuJoCo "
              f"{1e3 * residual:.4f} mm (IK's own {own:.4f} mm)")
    com_residual = float(np.linalg.norm(com[:2] - com_xy))
    worst = max(worst, com_residual)
    print(f"  CoM (x, y): target {(np.round(com_xy, 4) + 0.0).tolist()} m, residual in MuJoCo "
          f"{1e3 * com_residual:.4f} mm; height {com[2]:.4f} m")
    print(f"largest residual in MuJoCo: {1e3 * worst:.4f} mm (bound {1e3 * MAX_RESIDUAL_M:g} mm)")

    sim = Simulator(robot)
    sim.reset(KEYFRAME)
    ctrl_start = robot.keyframe_ctrl(KEYFRAME)
    ctrl_goal = np.array([result.q[robot.joint(a.joint).idx_q] for a in robot.actuators.values()])
    steps = max(1, round(args.duration / robot.timestep_s))
    ramp_steps = max(1, steps // 2)
    for k in range(steps):
        fraction = min(1.0, (k + 1) / ramp_steps)
        sim.step(position_target(ctrl_start + fraction * (ctrl_goal - ctrl_start)))
    print(f"simulated {sim.time_s:.3f} s holding the pose (ramp {ramp_steps * robot.timestep_s:.3f} s): "
          f"pelvis height {sim.base_z_m:.4f} m (bound >= {MIN_PELVIS_HEIGHT_M} m), "
          f"MuJoCo warnings: {sim.warnings or 'none'}")
    for palm in PALMS:
        error = float(np.linalg.norm(sim.site_pose(palm)[0] - targets[palm]))
        print(f"  {palm} on the plant: {1e3 * error:.2f} mm from its target")
    ok = result.converged and worst <= MAX_RESIDUAL_M and sim.base_z_m >= MIN_PELVIS_HEIGHT_M
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
