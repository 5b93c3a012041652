"""Whole-body inverse dynamics on the floating-base G1: a squat on its feet, in torque mode.

The controller (``mbctl.control.wbc``) solves one QP per control cycle for joint accelerations
and the contact forces at the four sole corners of each foot, under the floating-base dynamics
(Pinocchio), friction pyramids and torque limits, and sends the resulting joint torques. The
tasks: the centre of mass follows a squat (height down by up to 6 cm and back, 0.5 Hz), the
pelvis and torso keep their orientation, a light posture task and angular-momentum damping.
The Menagerie G1's position actuators are converted to torque motors at load time
(``position_to_motor``; force ranges kept), and the robot starts from the ``stand`` keyframe
with bent knees (``crouched_start``: straight knees make the CoM height uncontrollable).

Checked on the plant: the CoM tracking error is measured with MuJoCo's own centre of mass
(``subtree_com`` of the pelvis), and the QP's predicted vertical force against MuJoCo's contact
forces on the foot geoms (``measure_contacts``, ``mj_contactForce``).

Run::

    MENAGERIE_ROOT=/path/to/mujoco_menagerie python examples/07_g1_whole_body_control.py
    python examples/07_g1_whole_body_control.py --duration 1 --model-dir /path/to/unitree_g1

Exits 2 if the G1 model is not on this machine, and 1 if the CoM RMS error exceeds 5 mm, the QP
and MuJoCo disagree on the feet's vertical force by more than 5 % of m g (median), or the pelvis
drops below 0.5 m.
"""

from __future__ import annotations

import argparse
import sys

import mujoco
import numpy as np
import pinocchio as pin

from mbctl.control.wbc import (
    AngularMomentumDamping,
    ComAcceleration,
    FrameOrientationAcceleration,
    PostureAcceleration,
    TaskGains,
    WholeBodyController,
    foot_contact_from_model,
)
from mbctl.jobs.g1_wbc import crouched_start
from mbctl.jobs.robot_constants import FEET, KEYFRAME
from mbctl.robots import ModelFileError, ModelNotFoundError, load_robot
from mbctl.robots.edits import position_to_motor
from mbctl.sim import Simulator
from mbctl.sim.contacts import measure_contacts

SQUAT_M, SQUAT_HZ = 0.03, 0.5  # CoM height = start - SQUAT_M (1 - cos(2 pi f t))
MAX_COM_RMS_M, MAX_FORCE_ERROR = 5e-3, 0.05


def main() -> int:
    """Build the controller, squat, measure on the plant; returns the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=4.0, help="simulated time [s]")
    parser.add_argument("--model-dir", default=None, help="Menagerie unitree_g1 directory")
    args = parser.parse_args()
    if not args.duration > 0:
        parser.error(f"--duration must be > 0 s; got {args.duration}")
    try:
        robot = position_to_motor(load_robot("g1", model_dir=args.model_dir))
    except (ModelNotFoundError, ModelFileError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2

    sim = Simulator(robot)
    sim.reset(KEYFRAME)
    sim.set_state(crouched_start(robot), np.zeros(robot.nv))

    feet = [foot_contact_from_model(robot, foot) for foot in FEET]
    controller = WholeBodyController(robot, feet)
    model = controller.model
    com = ComAcceleration(TaskGains(weight=10.0, omega_rad_s=10.0, zeta=1.0))
    pelvis_up = FrameOrientationAcceleration("pelvis", model, TaskGains(5.0, 10.0, 1.0))
    torso_up = FrameOrientationAcceleration("torso_link", model, TaskGains(2.0, 10.0, 1.0))
    posture = PostureAcceleration(model, controller.joints.idx_v, TaskGains(0.05, 10.0, 1.0))
    for task in (com, pelvis_up, torso_up, posture, AngularMomentumDamping(TaskGains(0.2, 4.0, 1.0))):
        controller.add_task(task)
    controller.reset_contacts(sim.read_state())  # the feet hold where they stand
    upright = pin.SE3(np.eye(3), np.zeros(3))  # orientation targets: upright in the world
    pelvis_up.set_reference(upright)
    torso_up.set_reference(upright)
    posture.set_reference(controller.state.q.copy())
    c0 = controller.state.com().copy()

    m, d = sim.model, sim.data
    pelvis = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "pelvis")
    foot_geoms = {name: cs.contact.geoms for name, cs in controller.contacts.items()}
    mg = controller.state.mass * float(-m.opt.gravity[2])
    w = 2 * np.pi * SQUAT_HZ
    com_err, force_err = [], []
    for _ in range(int(round(args.duration / sim.control_period_s))):
        t = sim.time_s
        com.set_reference(c0 - [0, 0, SQUAT_M * (1 - np.cos(w * t))],  # p [m], v [m/s], a [m/s^2]
                          np.array([0, 0, -SQUAT_M * w * np.sin(w * t)]),
                          np.array([0, 0, -SQUAT_M * w * w * np.cos(w * t)]))
        sim.step(controller.compute(sim.read_state(), dt_s=sim.control_period_s))
        measured = measure_contacts(m, d, foot_geoms)
        mujoco.mj_forward(m, d)
        com_err.append(np.linalg.norm(d.subtree_com[pelvis] - com.p_ref))
        fz_qp = sum(controller.solution.forces_W[f][:, 2].sum() for f in FEET)
        force_err.append(abs(fz_qp - sum(measured[f].normal_n for f in FEET)) / mg)

    rms = float(np.sqrt(np.mean(np.square(com_err))))
    force = float(np.median(force_err))
    print(f"G1 squat {args.duration:g} s ({SQUAT_M * 200:.0f} cm deep at {SQUAT_HZ:g} Hz), torque mode:")
    print(f"  CoM RMS error (MuJoCo's CoM): {rms * 1e3:.2f} mm (bound {MAX_COM_RMS_M * 1e3:g} mm)")
    print(f"  QP vs MuJoCo vertical foot force: {force * 100:.2f} % of m g (median; bound 5 %)")
    print(f"  pelvis height at the end: {d.qpos[2]:.3f} m")
    return 0 if rms < MAX_COM_RMS_M and force < MAX_FORCE_ERROR and d.qpos[2] > 0.5 else 1


if __name__ == "__main__":
    sys.exit(main())
