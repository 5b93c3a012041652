"""Binding typed commands to a robot's actuators: names, shape and kind are checked once.

A binding is cached per (kind, names) so a control loop that sends new values to the same
actuators pays the name resolution only on its first command.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mbctl.robots.commands import Command, actuators_named, joint_actuators, kind_mismatch
from mbctl.robots.exceptions import CommandError
from mbctl.robots.fastmath import SMALL_VECTOR_MAX, any_outside
from mbctl.robots.model_pair import Robot


@dataclass(frozen=True)
class Binding:
    """Where a command's values go in ``MjData.ctrl``.

    Attributes:
        index: ctrl indices, one per value (a full command: ``arange(nu)``).
        full: Whether the command covers every actuator in order.
        ctrl_low: Lower ctrl bounds at ``index`` (-inf where unlimited).
        ctrl_high: Upper ctrl bounds at ``index`` (+inf where unlimited).
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
        """Whether any value lies outside its ctrl range."""
        if len(values) <= SMALL_VECTOR_MAX:  # plain Python beats four numpy calls there
            return any_outside(values.tolist(), self.low_list, self.high_list)
        return bool((values < self.ctrl_low).any() or (values > self.ctrl_high).any())


class CommandBinder:
    """Resolves commands against one robot's actuators (cached per kind and names)."""

    def __init__(self, robot: Robot):
        self.robot = robot
        self._by_joint = joint_actuators(robot.actuators)
        self._cache: dict[tuple, Binding] = {}
        self._last: tuple[object, object, int, Binding | None] = (None, None, -1, None)

    def bind(self, command: Command) -> Binding:
        """The binding of ``command``.

        Raises:
            CommandError: Wrong number of values, an actuator of another kind (e.g. a torque
                sent to a position actuator — never silently reinterpreted), or one actuator
                named twice (by its name and by its joint's).
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
        wrong = kind_mismatch(command.kind, infos)
        if wrong is not None:
            raise CommandError(wrong)
        index = np.array([a.index for a in infos], dtype=int)
        low = np.array([a.ctrl_range[0] for a in infos])
        high = np.array([a.ctrl_range[1] for a in infos])
        full = command.names is None or np.array_equal(index, np.arange(len(actuators)))
        limited = bool(np.isfinite(low).any() or np.isfinite(high).any())
        return Binding(index, bool(full), low, high, limited, tuple(low.tolist()), tuple(high.tolist()))
