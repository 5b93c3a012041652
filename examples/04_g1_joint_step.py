"""The Unitree G1: reset to a keyframe, raise one joint's position target, read sensors by name.

The G1 comes from MuJoCo Menagerie (``$MENAGERIE_ROOT``, the mujoco-menagerie package's cache,
or ``--model-dir``); it is never vendored. Its 29 actuators are position servos, so a command is
a position target [rad] per actuator name. Every actuator holds the target stored in the
keyframe "stand", except the left elbow, whose target is raised by 0.1 rad. The robot stands on
the floor throughout (floating base, contacts).

Run::

    MENAGERIE_ROOT=/path/to/mujoco_menagerie python examples/04_g1_joint_step.py
    python examples/04_g1_joint_step.py --duration 0.1 --model-dir /path/to/unitree_g1

Exits 2 (with the loader's message) if the G1 model is not on this machine or its folder lacks
a file, and 1 if the elbow ends more than 5 mrad from its target or the pelvis drops below 0.7 m.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from mbctl.robots import ModelFileError, ModelNotFoundError, load_robot
from mbctl.sim import Simulator, position_target

KEYFRAME = "stand"
JOINT = "left_elbow_joint"
DELTA_RAD = 0.1
SENSORS = ("imu-pelvis-angular-velocity", "imu-pelvis-linear-acceleration")
UNITS = {"gyro": "rad/s", "accelerometer": "m/s^2"}  # by MuJoCo sensor type
MAX_FINAL_ERROR_RAD = 5e-3  # the servo's steady-state sag under the forearm's weight is ~0.3 mrad
MIN_PELVIS_HEIGHT_M = 0.7  # the keyframe stands at 0.79 m


def main() -> int:
    """Load the G1, step its elbow, print and check; returns the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=1.0, help="simulated time [s]")
    parser.add_argument("--model-dir", default=None, help="Menagerie unitree_g1 directory")
    args = parser.parse_args()
    if not args.duration > 0:
        parser.error(f"--duration must be > 0 s; got {args.duration}")
    try:
        robot = load_robot("g1", model_dir=args.model_dir)
    except (ModelNotFoundError, ModelFileError) as exc:  # not on this machine, or incomplete
        print(exc, file=sys.stderr)
        return 2
    print(f"{robot}: {robot.source.origin}")

    sim = Simulator(robot)
    sim.reset(KEYFRAME)
    ctrl = robot.keyframe_ctrl(KEYFRAME)
    targets = {name: float(ctrl[a.index]) for name, a in robot.actuators.items()}
    actuator = robot.actuator_for_joint(JOINT)
    targets[actuator.name] += DELTA_RAD
    before = float(sim.joint_q(JOINT)[0])
    pelvis_before = sim.base_z_m

    steps = max(1, round(args.duration / robot.timestep_s))
    sim.step(position_target(targets), n=steps)
    final = float(sim.joint_q(JOINT)[0])
    target = targets[actuator.name]
    error = target - final
    print(f"{JOINT} (actuator {actuator.name!r}, kp {actuator.kp:g} N m/rad) after {sim.n_steps} "
          f"steps ({sim.time_s:.3f} s):")
    print(f"  before {before:+.5f} rad, target {target:+.5f} rad, final {final:+.5f} rad "
          f"(error {1e3 * error:+.3f} mrad, bound {1e3 * MAX_FINAL_ERROR_RAD:g} mrad)")
    print(f"  pelvis height: before {pelvis_before:.4f} m, final {sim.base_z_m:.4f} m "
          f"(bound >= {MIN_PELVIS_HEIGHT_M} m)")
    for name in SENSORS:
        unit = UNITS.get(robot.sensor(name).type, "")
        print(f"  sensor {name}: {(np.round(sim.sensor(name), 4) + 0.0).tolist()} {unit}")
    print(f"  contacts {sim.contact_count}, MuJoCo warnings: {sim.warnings or 'none'}")
    ok = abs(error) <= MAX_FINAL_ERROR_RAD and sim.base_z_m >= MIN_PELVIS_HEIGHT_M
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
