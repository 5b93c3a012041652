"""One command binder for every plant: names resolved once, kinds checked, duplicates refused, values clamped.

A :class:`Command` says its kind and, optionally, the actuators (or their joints) it addresses.
Every plant (the simulator, the simulator behind a link, a robot over DDS) binds it here, so the
same bad command meets the same error whichever plant it is sent to:

- a name that is neither an actuator nor an actuated joint: :class:`UnknownNameError`;
- one actuator named twice (by its name and by its joint's): :class:`CommandError`;
- a full command of the wrong size: :class:`CommandError`;
- a kind the plant's actuators do not take: :class:`CommandError` (the plant's
  :class:`BindingPolicy` says which kinds it takes and why; a torque is never silently sent to a
  position actuator).

What a plant may do with a value, its bounds, is the policy's too (the simulator: the actuator's
ctrlrange; a motor: its torque limit or the joint's range). :meth:`CommandBinder.clamp` clamps to
them and counts each clamped value per actuator, the one count every plant reports.

A binding is cached per (kind, names, size), so a control loop that sends new values to the same
actuators pays the name resolution only on its first command.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from mbctl.robots.commands import Command, CommandKind, actuators_named, joint_actuators, kind_mismatch
from mbctl.robots.exceptions import CommandError
from mbctl.robots.fastmath import SMALL_VECTOR_MAX, any_outside
from mbctl.robots.model_pair import Robot
from mbctl.robots.names import ActuatorInfo


class BindingPolicy(Protocol):
    """What a plant accepts: which command kinds drive which actuators, and each value's bounds."""

    def refuse(self, kind: CommandKind, actuators: Sequence[ActuatorInfo]) -> str | None:
        """Why a ``kind`` command cannot drive ``actuators`` (the error message), or None if it can."""

    def bounds(self, kind: CommandKind, actuators: Sequence[ActuatorInfo]) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds (n,) of the values (-inf/+inf where unbounded)."""


class CtrlRangePolicy:
    """The simulator's policy: a typed command drives actuators of its kind; values within ctrlrange."""

    def refuse(self, kind: CommandKind, actuators: Sequence[ActuatorInfo]) -> str | None:
        """See :class:`BindingPolicy` (the message of :func:`~mbctl.robots.commands.kind_mismatch`)."""
        return kind_mismatch(kind, actuators)

    def bounds(self, kind: CommandKind, actuators: Sequence[ActuatorInfo]) -> tuple[np.ndarray, np.ndarray]:
        """Each actuator's ctrlrange (MuJoCo clamps limited actuators the same way)."""
        return (np.array([a.ctrl_range[0] for a in actuators], dtype=float),
                np.array([a.ctrl_range[1] for a in actuators], dtype=float))


@dataclass(frozen=True)
class Binding:
    """Where a command's values go, and their bounds.

    Attributes:
        index: Actuator indices (ctrl order), one per value (a full command: ``arange(nu)``).
        full: Whether the command covers every actuator in order.
        ctrl_low: Lower bounds at ``index`` (-inf where unbounded).
        ctrl_high: Upper bounds at ``index`` (+inf where unbounded).
        limited: Whether any bound is finite.
        low_list: ``ctrl_low`` as Python floats (for the small-vector check).
        high_list: ``ctrl_high`` as Python floats.
    """

    index: np.ndarray
    full: bool
    ctrl_low: np.ndarray
    ctrl_high: np.ndarray
    limited: bool
    low_list: tuple[float, ...]
    high_list: tuple[float, ...]

    def out_of_range(self, values: np.ndarray) -> bool:
        """Whether any value lies outside its bounds."""
        if len(values) <= SMALL_VECTOR_MAX:  # plain Python beats four numpy calls there
            return any_outside(values.tolist(), self.low_list, self.high_list)
        return bool((values < self.ctrl_low).any() or (values > self.ctrl_high).any())


class CommandBinder:
    """Resolves commands against one robot's actuators under a plant's policy (cached per kind and names).

    Args:
        robot: The robot (its actuators, by name and by joint).
        policy: What the plant accepts (default: the simulator's, :class:`CtrlRangePolicy`).

    Attributes:
        clamp_counts: Values clamped, per actuator (nu,), counted by :meth:`clamp`.
        clamped_commands: Commands in which :meth:`clamp` clamped at least one value.
    """

    def __init__(self, robot: Robot, policy: BindingPolicy | None = None):
        self.robot = robot
        self.policy: BindingPolicy = policy or CtrlRangePolicy()
        self._by_joint = joint_actuators(robot.actuators)
        self._cache: dict[tuple, Binding] = {}
        self._last: tuple[object, object, int, Binding | None] = (None, None, -1, None)
        self.clamp_counts = np.zeros(robot.nu, dtype=int)
        self.clamped_commands = 0

    def bind(self, command: Command) -> Binding:
        """The binding of ``command``.

        Raises:
            CommandError: Wrong number of values, a kind the policy refuses (e.g. a torque sent
                to a position actuator of the simulator — never silently reinterpreted), or one
                actuator named twice (by its name and by its joint's).
            UnknownNameError: A name that is neither an actuator nor an actuated joint.
        """
        kind, names, size, binding = self._last
        if command.kind is kind and command.names is names and command.values.size == size:
            return binding  # type: ignore[return-value]  # a loop's commands: the last binding again
        key = (command.kind, command.names, command.values.size)
        binding = self._cache.get(key)  # (hashing the key calls the enum's Python-level __hash__)
        if binding is None:
            binding = self._cache[key] = self._resolve(command)
        self._last = (command.kind, command.names, command.values.size, binding)
        return binding

    def clamp(self, binding: Binding, values: np.ndarray) -> np.ndarray:
        """``values`` clamped to the binding's bounds, each clamped value counted per actuator."""
        if not (binding.limited and binding.out_of_range(values)):
            return values
        hit = (values < binding.ctrl_low) | (values > binding.ctrl_high)
        self.clamp_counts[binding.index[hit]] += 1
        self.clamped_commands += 1
        return np.clip(values, binding.ctrl_low, binding.ctrl_high)

    def clamped(self) -> dict[str, int]:
        """How many values were clamped, per actuator name (non-zero only)."""
        names = list(self.robot.actuators)
        return {names[i]: int(c) for i, c in enumerate(self.clamp_counts) if c}

    def reset_counts(self) -> None:
        """Zero the clamp counts."""
        self.clamp_counts[:] = 0
        self.clamped_commands = 0

    def _resolve(self, command: Command) -> Binding:
        actuators = self.robot.actuators
        if command.names is None:
            if command.values.size != len(actuators):
                raise CommandError(
                    f"{command.kind.value} command for {self.robot.name!r} needs {len(actuators)} "
                    f"values (one per actuator: {', '.join(actuators)}); got {command.values.size}"
                )
            infos = list(actuators.values())
        else:
            infos = actuators_named(command.names, actuators, self._by_joint, f"{command.kind.value} command")
        wrong = self.policy.refuse(command.kind, infos)
        if wrong is not None:
            raise CommandError(wrong)
        index = np.array([a.index for a in infos], dtype=int)
        low, high = self.policy.bounds(command.kind, infos)
        full = command.names is None or np.array_equal(index, np.arange(len(actuators)))
        limited = bool(np.isfinite(low).any() or np.isfinite(high).any())
        for arr in (index, low, high):
            arr.setflags(write=False)
        return Binding(index, bool(full), low, high, limited, tuple(low.tolist()), tuple(high.tolist()))
