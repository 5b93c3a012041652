"""Whole-body inverse dynamics on the floating-base G1: a squat on its feet, in torque mode.

The controller (``mbctl.control.wbc``) solves one QP per control cycle for joint accelerations
and the contact forces at the four sole corners of each foot, under the floating-base dynamics
(Pinocchio), friction pyramids and torque limits, and sends the resulting joint torques. The
tasks come from the task layer (``mbctl.control.tasks``, the same task types differential IK
uses, here at the acceleration level): the centre of mass follows a squat (height down by up to
6 cm and back, 0.5 Hz), the pelvis and torso keep their orientation, a light posture task and
angular-momentum damping. The Menagerie G1's position actuators are converted to torque motors at
load time (``position_to_motor``; force ranges kept), and the robot starts from the ``stand``
keyframe with bent knees (``crouched_start``: straight knees make the CoM height uncontrollable).
The control loop (``mbctl.control.run``) drives it on the simulator, as any controller.

Checked on the plant: a ``PlantMonitor`` measures the CoM with MuJoCo's own centre of mass and
MuJoCo's contact forces on the foot geoms, against the QP's predicted vertical force.

Run::

    MENAGERIE_ROOT=/path/to/mujoco_menagerie python examples/07_g1_whole_body_control.py
    python examples/07_g1_whole_body_control.py --duration 1 --model-dir /path/to/unitree_g1

Exits 2 if the G1 model is not on this machine, and 1 if the CoM RMS error exceeds 5 mm, the QP
and MuJoCo disagree on the feet's vertical force by more than 5 % of m g (median), or the robot
fell.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
import pinocchio as pin

from mbctl.control import run
from mbctl.control.tasks import (
    AccelerationGains,
    AngularMomentumTask,
    ComTask,
    FrameOrientationTask,
    PostureTask,
)
from mbctl.control.wbc import Scheduled, WholeBodyController, foot_contact_from_model
from mbctl.robots import ModelFileError, ModelNotFoundError, RobotState, load_robot
from mbctl.robots.edits import position_to_motor
from mbctl.robots.g1 import FEET, G1_FALL, KEYFRAME, crouched_start
from mbctl.sim import Simulator
from mbctl.sim.monitor import PlantMonitor

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
    gains = AccelerationGains(omega_rad_s=10.0, zeta=1.0)  # the task error's closed-loop dynamics
    com = ComTask(cost=10.0, servo=gains)
    pelvis_up = FrameOrientationTask("pelvis", model, cost=5.0, servo=gains)
    torso_up = FrameOrientationTask("torso_link", model, cost=2.0, servo=gains)
    posture = PostureTask(model, cost=0.05, servo=gains)
    for task in (com, pelvis_up, torso_up, posture, AngularMomentumTask(0.2, servo=AccelerationGains(4.0))):
        controller.add_task(task)
    controller.reset_contacts(sim.read_state())  # the feet hold where they stand
    upright = pin.SE3.Identity()  # orientation targets: upright in the world
    pelvis_up.set_target(upright)
    torso_up.set_target(upright)
    posture.set_target(controller.state.q.copy())
    c0 = controller.state.com().copy()
    w = 2 * np.pi * SQUAT_HZ

    def squat(t: float, state: RobotState) -> None:
        """The CoM target at time t [s]: position [m], velocity [m/s], acceleration [m/s^2]."""
        com.set_target(c0 - [0, 0, SQUAT_M * (1 - np.cos(w * t))], [0, 0, -SQUAT_M * w * np.sin(w * t)],
                       [0, 0, -SQUAT_M * w * w * np.cos(w * t)])

    foot_geoms = {name: cs.contact.geoms for name, cs in controller.contacts.items()}
    plant = PlantMonitor(sim, foot_geoms, fall_rule=G1_FALL.reason).attach()
    mg = plant.mass_kg * float(-sim.model.opt.gravity[2])
    com_err, force_err = [], []

    def measure(k, state, reference, command) -> bool:
        """After each cycle: MuJoCo's CoM and foot forces against the targets and the QP."""
        com_err.append(np.linalg.norm(plant.com_W - com.target))
        fz_qp = sum(controller.solution.forces_W[f][:, 2].sum() for f in FEET)
        force_err.append(abs(fz_qp - sum(plant.contacts[f].normal_n for f in FEET)) / mg)
        return plant.fall_reason is not None  # stop if the robot fell

    run(sim, Scheduled(controller, squat), None, args.duration, on_step=measure)
    rms = float(np.sqrt(np.mean(np.square(com_err))))
    force = float(np.median(force_err))
    print(f"G1 squat {args.duration:g} s ({SQUAT_M * 200:.0f} cm deep at {SQUAT_HZ:g} Hz), torque mode:")
    print(f"  CoM RMS error (MuJoCo's CoM): {rms * 1e3:.2f} mm (bound {MAX_COM_RMS_M * 1e3:g} mm)")
    print(f"  QP vs MuJoCo vertical foot force: {force * 100:.2f} % of m g (median; bound 5 %)")
    print(f"  fell: {plant.fall_reason or 'no'}")
    return 0 if rms < MAX_COM_RMS_M and force < MAX_FORCE_ERROR and plant.fall_reason is None else 1


if __name__ == "__main__":
    sys.exit(main())
