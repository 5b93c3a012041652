"""Load-time model edits that derive a new Robot from an existing one (MjSpec + Pinocchio)."""

from __future__ import annotations

from collections.abc import Iterable

import mujoco
import numpy as np
from mbctl.robots.model_pair import Robot


def position_to_motor(robot: Robot, actuators: Iterable[str] | None = None) -> Robot:
    """Turn position (or velocity) actuators into torque motors, so torque controllers can run.

    Each converted actuator becomes a motor with gear 1 whose ctrlrange is the actuator's force
    range (from ``forcerange`` or the joint's ``actuatorfrcrange``); ctrl then means [N m].

    Args:
        robot: The robot to convert (unchanged).
        actuators: Names to convert; default: every position and velocity actuator.

    Returns:
        A new Robot whose ``source.edits`` records the conversion.
    """
    names = list(actuators) if actuators is not None else [
        a.name for a in robot.actuators.values() if a.kind in ("position", "velocity")
    ]
    infos = [robot.actuator(n) for n in names]

    def edit(spec: mujoco.MjSpec) -> None:
        for info in infos:
            act = spec.actuator(info.name)
            act.set_to_motor()
            act.gear = np.array([info.gear, 0, 0, 0, 0, 0])
            lo, hi = info.force_range
            if np.isfinite(lo) and np.isfinite(hi):
                act.ctrlrange = np.array([lo, hi])
                act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
            else:
                act.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
            act.inheritrange = 0
        # keyframe ctrl values were position targets; as torques they would be meaningless
        for key in spec.keys:
            key.ctrl = np.zeros(0)

    return robot.with_edits(f"position actuators -> torque motors: {len(infos)} actuators", mj_edit=edit)
