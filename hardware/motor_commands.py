"""Typed commands into the motor slots of a LowCmd_: each kind maps explicitly, nothing is reinterpreted.

A motor applies ``tau + kp (q* - q) + kd (dq* - dq)``. The command kinds map to it as:

- torque: ``tau`` [N m] with ``kp = kd = 0`` (and ``q* = dq* = 0``);
- position target: ``q*`` [rad] with the motor's ``kp`` and ``kd`` (``dq* = 0``, ``tau = 0``);
- velocity target: ``dq*`` [rad/s] with the motor's ``kd`` (``kp = 0``, ``tau = 0``);
- raw ctrl (MuJoCo's own units): refused, the robot has no ctrl.

Commands are bound by the one :class:`~mbctl.robots.command_binding.CommandBinder` every plant
uses (names, duplicates, size), under :class:`MotorPolicy`: every motor takes every kind (the
firmware runs the same law), so unlike the simulator the kind is not checked against the model's
actuators; position and velocity targets need gains (:class:`MotorGains`, by default the model's
position actuators' ``kp`` and ``kv``). Torques are clamped to the motor's torque limit and
position targets to the joint's range; each clamped value is counted per actuator.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from mbctl.robots.command_binding import Binding, CommandBinder
from mbctl.robots.commands import Command, CommandKind
from mbctl.robots.exceptions import CommandError
from mbctl.robots.model_pair import Robot
from mbctl.robots.names import ActuatorInfo
from mbctl.unitree.motors import MotorMap

#: Default damping gain: the motor's torque limit is reached at this joint speed [rad/s].
DAMPING_SATURATION_RAD_S = 10.0


@dataclass(frozen=True, eq=False)
class MotorGains:
    """PD gains per motor (motor order), read-only; NaN where a motor has none.

    Attributes:
        kp: Stiffness (n,) [N m/rad] for position targets.
        kd: Damping (n,) [N m s/rad] for position and velocity targets.
    """

    kp: np.ndarray
    kd: np.ndarray

    def __post_init__(self) -> None:
        kp = np.array(self.kp, dtype=float)
        kd = np.array(self.kd, dtype=float)
        if kp.shape != kd.shape or kp.ndim != 1:
            raise CommandError(f"kp and kd must be vectors of one length; got {kp.shape} and {kd.shape}")
        if np.any(kp[np.isfinite(kp)] < 0) or np.any(kd[np.isfinite(kd)] < 0):
            raise CommandError("motor gains must be >= 0 (NaN where a motor has none)")
        for arr, name in ((kp, "kp"), (kd, "kd")):
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    @classmethod
    def from_actuators(cls, robot: Robot, motors: MotorMap) -> MotorGains:
        """The model's position actuators' ``kp`` and ``kv`` (NaN for motors driven otherwise)."""
        infos = [robot.actuator_for_joint(j) for j in motors.joints]
        return cls(np.array([a.kp if a.kind == "position" else np.nan for a in infos]),
                   np.array([a.kv if a.kind == "position" else np.nan for a in infos]))

    def by_joint(self, motors: MotorMap) -> dict[str, tuple[float, float]]:
        """(kp, kd) by joint name, for the motors that have gains."""
        return {j: (float(self.kp[i]), float(self.kd[i])) for i, j in enumerate(motors.joints)
                if np.isfinite(self.kp[i]) and np.isfinite(self.kd[i])}

    @classmethod
    def uniform(cls, n: int, kp: float, kd: float) -> MotorGains:
        """The same gains on ``n`` motors."""
        return cls(np.full(n, float(kp)), np.full(n, float(kd)))


def default_damping(motors: MotorMap) -> np.ndarray:
    """Damping gains (n,) [N m s/rad]: each motor's torque limit over :data:`DAMPING_SATURATION_RAD_S`."""
    return motors.tau_max / DAMPING_SATURATION_RAD_S


class MotorPolicy:
    """What the robot's motors accept, for the one :class:`~mbctl.robots.command_binding.CommandBinder`.

    Every motor runs the same law, so every motor takes torque, position and velocity commands
    (unlike the simulator the kind is not checked against the model's actuators); a raw ctrl
    command is refused, an actuator without a motor is refused, and position and velocity
    targets need gains. Torques are bounded by the motor's torque limit, position targets by the
    joint's range.

    Args:
        robot: The robot model.
        motors: The motor map.
        gains: Gains for position and velocity targets.
    """

    def __init__(self, robot: Robot, motors: MotorMap, gains: MotorGains):
        self.motors = motors
        self.gains = gains
        motor_of_actuator = np.full(robot.nu, -1)
        motor_of_actuator[motors.actuator] = np.arange(motors.n)
        self.motor_of_actuator = motor_of_actuator

    def refuse(self, kind: CommandKind, actuators: Sequence[ActuatorInfo]) -> str | None:
        """Why the motors cannot take a ``kind`` command for ``actuators``, or None."""
        if kind is CommandKind.CTRL:
            return ("a raw ctrl command is MuJoCo's own units; the robot's motors take torque, "
                    "position_target or velocity_target commands")
        motors = self.motor_of_actuator[[a.index for a in actuators]]
        if np.any(motors < 0):
            bad = [a.name for a, m in zip(actuators, motors, strict=True) if m < 0]
            return f"actuators {bad} drive no motor of the robot"
        kp, kd = self.gains.kp[motors], self.gains.kd[motors]
        need = {CommandKind.POSITION: np.isfinite(kp) & np.isfinite(kd),
                CommandKind.VELOCITY: np.isfinite(kd)}.get(kind)
        if need is not None and not need.all():
            missing = [self.motors.joints[m] for m in motors[~need]]
            return (f"a {kind.value} target needs motor gains; none for {missing[:6]}: give "
                    "MotorGains (kp, kd per motor) to the interface")
        return None

    def bounds(self, kind: CommandKind, actuators: Sequence[ActuatorInfo]) -> tuple[np.ndarray, np.ndarray]:
        """Torque: the motor's limit; position: the joint's range; velocity: unbounded."""
        motors = self.motor_of_actuator[[a.index for a in actuators]]
        if kind is CommandKind.TORQUE:
            return -self.motors.tau_max[motors], self.motors.tau_max[motors].copy()
        if kind is CommandKind.POSITION:
            return self.motors.q_low[motors].copy(), self.motors.q_high[motors].copy()
        return np.full(motors.size, -np.inf), np.full(motors.size, np.inf)


@dataclass(frozen=True)
class _Slots:
    slots: np.ndarray | slice  # motor slots of the values
    kp: np.ndarray
    kd: np.ndarray


class MotorCommandWriter:
    """Writes commands into a ``LowCmd_`` record's ``motor_cmd``, bound by the one command binder.

    Args:
        robot: The robot model (names and actuator order of full commands).
        motors: The motor map.
        gains: Gains for position and velocity targets.

    Attributes:
        binder: The command binder (names, duplicates, size, kind, bounds; its clamp counts).
    """

    def __init__(self, robot: Robot, motors: MotorMap, gains: MotorGains):
        if gains.kp.size != motors.n:
            raise CommandError(f"gains for {gains.kp.size} motors; the robot has {motors.n}")
        self.robot = robot
        self.motors = motors
        self.gains = gains
        self.policy = MotorPolicy(robot, motors, gains)
        self.binder = CommandBinder(robot, self.policy)
        self._slots: dict[int, _Slots] = {}
        self._fields: tuple[np.ndarray, dict[str, np.ndarray]] | None = None  # a motor_cmd's field views

    def _slots_of(self, binding: Binding) -> _Slots:
        found = self._slots.get(id(binding))
        if found is None:
            motors = self.policy.motor_of_actuator[binding.index]
            slots: np.ndarray | slice = motors
            if np.array_equal(motors, np.arange(motors.size)):
                slots = slice(0, motors.size)
            # the binder caches its bindings for its lifetime, so their ids stay unique
            found = self._slots[id(binding)] = _Slots(slots, self.gains.kp[motors], self.gains.kd[motors])
        return found

    def write(self, command: Command, motor_cmd: np.ndarray) -> None:
        """Write ``command`` into ``motor_cmd`` (the ``LowCmd_``'s (35,) motor records), clamped and counted.

        Raises:
            CommandError: A ctrl command, the wrong number of values, one actuator named twice,
                or targets without gains.
            UnknownNameError: A name that is neither an actuator nor an actuated joint.
        """
        b = self.binder.bind(command)
        values = self.binder.clamp(b, command.values)
        m = self._slots_of(b)
        s, kind = m.slots, command.kind
        # the record's field views, made once per record (a field read of a structured array is ~0.5 us)
        if self._fields is None or self._fields[0] is not motor_cmd:
            self._fields = motor_cmd, {name: motor_cmd[name] for name in ("tau", "q", "dq", "kp", "kd")}
        f = self._fields[1]
        if kind is CommandKind.TORQUE:
            f["tau"][s] = values
            f["q"][s] = f["dq"][s] = f["kp"][s] = f["kd"][s] = 0.0
        elif kind is CommandKind.POSITION:
            f["q"][s] = values
            f["kp"][s] = m.kp
            f["kd"][s] = m.kd
            f["dq"][s] = f["tau"][s] = 0.0
        else:
            f["dq"][s] = values
            f["kd"][s] = m.kd
            f["q"][s] = f["kp"][s] = f["tau"][s] = 0.0

    def saturations(self) -> dict[str, int]:
        """How many values were clamped, per actuator name (non-zero only)."""
        return self.binder.clamped()


def write_damping(motor_cmd: np.ndarray, kd: npt.ArrayLike) -> None:
    """The damping command on the first ``len(kd)`` motors: ``kp = 0``, ``kd`` given, no target, no torque."""
    kd = np.asarray(kd, dtype=float)
    s = slice(0, kd.size)
    motor_cmd["kd"][s] = kd
    motor_cmd["q"][s] = motor_cmd["dq"][s] = motor_cmd["tau"][s] = motor_cmd["kp"][s] = 0.0
