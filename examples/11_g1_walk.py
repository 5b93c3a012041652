"""The G1 walks after a velocity command that your own code changes every control cycle.

A joystick stand-in (``joystick(t)``: forward, then a left turn while walking, then sideways, then
stop) sets the command of the walking controller (``WalkingController``: footsteps, a DCM plan with
step adaptation, swing feet and force-ramped contact switches on the whole-body QP, torques only;
``quick_gait()``'s options, as ``g1-walk``'s default) each cycle, through a three-line controller
of your own (``reset``, ``compute``) that the control loop runs on the in-process G1. The walk is
checked in the plant: MuJoCo's fall rule (``PlantMonitor``), the pelvis's displacement and turn, the
footsteps taken.

The same controller object runs over the G1's low-level DDS (``UnitreeG1`` against
``mbctl serve g1 --start crouched``) as in ``10_g1_over_dds.py``; ``mbctl g1-walk ... --interface
dds`` does it from the command line.

Run::

    MENAGERIE_ROOT=/path/to/mujoco_menagerie python examples/11_g1_walk.py
    python examples/11_g1_walk.py --duration 4

Exits 2 without the G1 model, 1 if the robot fell.
"""

from __future__ import annotations

import argparse
import math
import sys

import numpy as np

from mbctl.control import run
from mbctl.control.wbc import WalkingController, WBCConfig, quick_gait
from mbctl.robots import ModelFileError, ModelNotFoundError, load_robot, quat_xyzw_yaw
from mbctl.robots.edits import position_to_motor
from mbctl.robots.g1 import FEET, G1_FALL, KEYFRAME, PELVIS, TORSO, crouched_start
from mbctl.robots.interface import RobotState
from mbctl.sim import Simulator
from mbctl.sim.monitor import PlantMonitor


def joystick(t: float) -> tuple[float, float, float]:
    """Your command at time t [s]: (forward [m/s], leftward [m/s], turning [rad/s]) in the body frame."""
    if t < 6.0:
        return 0.3, 0.0, 0.0
    if t < 10.0:
        return 0.2, 0.0, 0.4
    if t < 13.0:
        return 0.0, 0.15, 0.0
    return 0.0, 0.0, 0.0


class JoystickWalker:
    """Your controller: sets the walking command from the joystick each cycle, then walks."""

    reference_type = None  # it carries its own targets (control.run is given reference=None)

    def __init__(self, walker: WalkingController):
        self.walker = walker
        self.t0: float | None = None

    def reset(self) -> None:
        """Restart the joystick's clock and the walk (the control loop calls this first)."""
        self.t0 = None
        self.walker.reset()

    def compute(self, state: RobotState, reference: object = None):
        """This cycle's command from the joystick, then the walking controller's torques."""
        if self.t0 is None:
            self.t0 = state.time_s
        self.walker.set_command(joystick(state.time_s - self.t0))
        return self.walker.compute(state)


def main() -> int:
    """Walk the joystick's commands for --duration seconds; 0 if the G1 stayed up."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=16.0, help="simulated time (s)")
    parser.add_argument("--model-dir", default=None, help="the unitree_g1 folder (else MENAGERIE_ROOT)")
    args = parser.parse_args()
    try:
        robot = position_to_motor(load_robot("g1", model_dir=args.model_dir))
    except (ModelNotFoundError, ModelFileError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    q0 = crouched_start(robot)
    sim = Simulator(robot)
    sim.reset(KEYFRAME)
    sim.set_state(q0, np.zeros(robot.nv))
    # the quick gait (g1-walk's default: a step every 0.31 s); no QP solution: damping, and see it fall
    config = quick_gait(wbc=WBCConfig(on_infeasible="damp"))
    arms = {"left_shoulder_pitch_joint": "right_hip_pitch_joint",  # each arm swings against the other leg
            "right_shoulder_pitch_joint": "left_hip_pitch_joint"}
    walker = WalkingController(robot, FEET, PELVIS, TORSO, q0, config, arm_swing=arms,
                               torso_counter_yaw=("left_hip_pitch_joint", "right_hip_pitch_joint"))
    feet = {name: contact.contact.geoms for name, contact in walker.wbc.contacts.items()}
    monitor = PlantMonitor(sim, feet, sites=FEET, fall_rule=G1_FALL.reason).attach()
    walker.contact_force = lambda foot: monitor.contacts[foot].normal_n if monitor.contacts else None
    log = run(sim, JoystickWalker(walker), None, args.duration,
              on_step=lambda k, state, reference, command: monitor.fall_reason is not None)
    start, end = log.q[0], sim.read_state().q
    moved = np.hypot(*(end[:2] - start[:2]))
    turned = math.degrees(math.remainder(quat_xyzw_yaw(end[3:7]) - quat_xyzw_yaw(start[3:7]), 2 * math.pi))
    print(f"walked {log.t_s[-1] - log.t_s[0]:.2f} s: {walker.steps} steps, pelvis moved {moved:.3f} m, "
          f"turned {turned:.1f} deg")
    print(f"last command applied: {tuple(round(v, 3) for v in walker.command.applied)} "
          f"(limited by: {', '.join(walker.command.limited_by) or 'nothing'})")
    if monitor.fall_reason is not None:
        print(f"FELL at {monitor.fall_time_s:.2f} s: {monitor.fall_reason}")
        return 1
    print("fell: no")
    return 0


if __name__ == "__main__":
    sys.exit(main())
