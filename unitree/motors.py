"""Where a ``unitree_hg`` robot's motors sit in its model: one table of joint names, resolved once.

The ``unitree_hg`` LowCmd_/LowState_ messages carry :data:`MOTOR_SLOTS` motor records; a robot
uses the first ``n`` of them in the order of its :class:`~mbctl.unitree.tables.MotorTable` (the
G1's tables are data in :mod:`mbctl.unitree.tables`; another ``unitree_hg`` robot is one more
table, no code).

:class:`MotorMap` derives, once, where each motor sits in a :class:`~mbctl.robots.model_pair.Robot`
(its q and v indices in Pinocchio's convention, its actuator, its limits), so the hot path moves
whole arrays with one fancy index.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from mbctl.robots.exceptions import UnknownNameError
from mbctl.robots.model_pair import Robot
from mbctl.robots.names import ActuatorInfo
from mbctl.unitree.exceptions import MotorTableError
from mbctl.unitree.tables import G1_29DOF, MotorTable

#: Motor slots in the ``unitree_hg`` ``LowCmd_`` / ``LowState_`` messages.
MOTOR_SLOTS = 35

#: ``LowCmd_.mode_pr``: 0 commands the ankles (and waist) as pitch/roll joints, as the Menagerie
#: model has them; 1 ("AB") commands the parallel linkage's motors directly (not modelled here).
MODE_PR = 0
#: ``MotorCmd_.mode``: 1 enables the motor, 0 leaves it free.
MOTOR_ENABLED = 1


def motor_index(joint: str, table: MotorTable | Sequence[str] = G1_29DOF) -> int:
    """The motor index of joint ``joint`` in ``table`` (default: the 29-dof G1's).

    Raises:
        UnknownNameError: A joint the table does not drive (the message names the table's joints).
    """
    joints = _joints(table)
    try:
        return joints.index(joint)
    except ValueError:
        raise UnknownNameError("motor joint", joint, joints) from None


def motor_joint(index: int, table: MotorTable | Sequence[str] = G1_29DOF) -> str:
    """The joint name of motor ``index`` in ``table`` (default: the 29-dof G1's).

    Raises:
        UnknownNameError: An index outside 0..len(table)-1 (slots above it are unused).
    """
    joints = _joints(table)
    if not 0 <= index < len(joints):
        raise UnknownNameError("motor index", str(index), [str(i) for i in range(len(joints))])
    return joints[index]


def _joints(table: MotorTable | Sequence[str]) -> tuple[str, ...]:
    return table.joints if isinstance(table, MotorTable) else tuple(table)


@dataclass(frozen=True, eq=False)
class MotorMap:
    """Where each motor of the table sits in a robot (index arrays derived once, read-only).

    Attributes:
        joints: Joint name per motor (n,).
        idx_q: Index in q (Pinocchio convention) per motor (n,).
        idx_v: Index in v per motor (n,).
        actuator: Index in the robot's actuators (ctrl order) per motor (n,).
        q_low: Lower joint limit [rad] per motor (n,).
        q_high: Upper joint limit [rad] per motor (n,).
        tau_max: Torque limit [N m] per motor (n,): the actuator's force range (the joint's
            ``actuatorfrcrange`` in the Menagerie G1), or its ctrlrange for a motor actuator.
    """

    joints: tuple[str, ...]
    idx_q: np.ndarray
    idx_v: np.ndarray
    actuator: np.ndarray
    q_low: np.ndarray
    q_high: np.ndarray
    tau_max: np.ndarray

    @property
    def n(self) -> int:
        """Number of motors."""
        return len(self.joints)

    @classmethod
    def for_robot(cls, robot: Robot, table: MotorTable | Sequence[str] = G1_29DOF) -> MotorMap:
        """Resolve ``table`` in ``robot`` (default: the 29-dof G1's table).

        Raises:
            MotorTableError: A table joint the robot lacks, an actuated joint the table lacks, or
                a motor without a finite torque limit.
        """
        name = table.name if isinstance(table, MotorTable) else "given"
        joints = _joints(table)
        missing = [j for j in joints if j not in robot.joints]
        driven = {a.joint for a in robot.actuators.values() if a.joint}
        extra = sorted(driven - set(joints))
        undriven = [j for j in joints if j not in driven]
        if missing or extra or undriven:
            raise MotorTableError(
                f"the robot does not match the {name} motor table: "
                + "; ".join(p for p in (
                    f"joints missing from the robot: {missing}" if missing else "",
                    f"actuated joints without a motor slot: {extra}" if extra else "",
                    f"motor joints without an actuator: {undriven}" if undriven else "") if p)
                + " (load the robot the table is for, e.g. the Menagerie G1: load_robot('g1'))")
        layouts = [robot.joint(j) for j in joints]
        acts = [robot.actuator_for_joint(j) for j in joints]
        low = robot.pin_model.lowerPositionLimit
        high = robot.pin_model.upperPositionLimit
        tau_max = np.array([_torque_limit(a) for a in acts])
        if not np.all(np.isfinite(tau_max)):
            bad = [t for t, x in zip(joints, tau_max, strict=True) if not np.isfinite(x)]
            raise MotorTableError(f"motors without a torque limit in the model: {bad}")
        arrays = [np.array([j.idx_q for j in layouts]), np.array([j.idx_v for j in layouts]),
                  np.array([a.index for a in acts]),
                  np.array([low[j.idx_q] for j in layouts]), np.array([high[j.idx_q] for j in layouts]),
                  tau_max]
        for arr in arrays:
            arr.setflags(write=False)
        return cls(joints, *arrays)


def _torque_limit(actuator: ActuatorInfo) -> float:
    """The largest |torque| [N m] an actuator can apply: its force range, else a motor's ctrlrange."""
    lo, hi = actuator.force_range
    if not (np.isfinite(lo) and np.isfinite(hi)) and actuator.kind == "torque":
        lo, hi = (actuator.gear * x for x in actuator.ctrl_range)
    return float(min(abs(lo), abs(hi)))
