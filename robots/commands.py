"""Typed actuator commands: a command says what it is — torque, position or velocity target.

The command types live in robots/ (the robot API) so that control/ can produce them without
importing sim/. A command either covers every actuator (``values`` of shape (nu,), in actuator order) or names
the actuators it addresses (by actuator name or by the name of the joint an actuator drives).
Actuators a partial command does not name keep their previous ctrl (MuJoCo holds ctrl).

Commands are immutable (frozen dataclass, read-only array) and validated at construction for
finiteness; the simulator checks names, shape and actuator kind when it first sees a command.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from enum import Enum

import numpy as np
import numpy.typing as npt

from mbctl.robots.exceptions import CommandError, UnknownNameError
from mbctl.robots.fastmath import all_finite
from mbctl.robots.names import ActuatorInfo


class CommandKind(str, Enum):
    """What a command's values mean, and which actuator kind accepts it."""

    TORQUE = "torque"  # [N m] or [N] through the gear of a motor actuator
    POSITION = "position"  # target [rad] or [m] of a position actuator
    VELOCITY = "velocity"  # target [rad/s] or [m/s] of a velocity actuator
    CTRL = "ctrl"  # MjData.ctrl as is, in each actuator's own units: any actuator kind


@dataclass(frozen=True, eq=False, init=False)
class Command:
    """One command: its kind, values and (optionally) the names they address.

    Attributes:
        kind: Torque, position target or velocity target.
        values: Values, shape (nu,) for a full command or (len(names),); read-only copy.
        names: Actuator or joint names the values address; None for a full vector.

    Raises:
        CommandError: Values that are not a vector, a names/values length mismatch, or
            non-finite values (named by position or name).
    """

    kind: CommandKind
    values: np.ndarray
    names: tuple[str, ...] | None

    def __init__(
        self, kind: CommandKind, values: npt.ArrayLike, names: tuple[str, ...] | None = None
    ) -> None:
        # Hand-written __init__ (validate, then set each field once): commands are built every
        # control cycle, and this halves the cost of the generated __init__ + __post_init__.
        arr = np.array(values, dtype=float, ndmin=1)
        if arr.ndim != 1:
            raise CommandError(f"{kind.value} command must be a vector; got shape {arr.shape}")
        if names is not None and len(names) != arr.size:
            raise CommandError(
                f"{kind.value} command names {len(names)} actuators but has {arr.size} values"
            )
        if not all_finite(arr.tolist()):  # ~5x cheaper than np.isfinite on small vectors
            bad = np.flatnonzero(~np.isfinite(arr))
            where = [names[i] for i in bad] if names else bad.tolist()
            raise CommandError(
                f"{kind.value} command must be finite; got {arr[bad].tolist()} at {where}"
            )
        arr.flags.writeable = False
        setattr_ = object.__setattr__
        setattr_(self, "kind", kind)
        setattr_(self, "values", arr)
        setattr_(self, "names", names)

    @property
    def key(self) -> tuple[CommandKind, tuple[str, ...] | None]:
        """What the command addresses (kind and names), for caching its binding."""
        return self.kind, self.names


def _make(kind: CommandKind, values: npt.ArrayLike | Mapping[str, float]) -> Command:
    if type(values) is np.ndarray:  # the control-loop case; skips the slower ABC check below
        return Command(kind, values)
    if isinstance(values, Mapping):
        names = tuple(values)
        return Command(kind, np.fromiter(values.values(), float, len(names)), names)
    try:
        return Command(kind, np.asarray(values, dtype=float))
    except (TypeError, ValueError) as exc:
        if isinstance(exc, CommandError):
            raise
        raise CommandError(f"{kind.value} command values must be numbers; got {values!r}") from exc


def torque(values: npt.ArrayLike | Mapping[str, float]) -> Command:
    """Torque command [N m] (or [N]): a full vector (nu,) or ``{actuator_or_joint: value}``."""
    return _make(CommandKind.TORQUE, values)


def position_target(values: npt.ArrayLike | Mapping[str, float]) -> Command:
    """Position-target command [rad] (or [m]): a full vector (nu,) or a name mapping."""
    return _make(CommandKind.POSITION, values)


def velocity_target(values: npt.ArrayLike | Mapping[str, float]) -> Command:
    """Velocity-target command [rad/s] (or [m/s]): a full vector (nu,) or a name mapping."""
    return _make(CommandKind.VELOCITY, values)


def ctrl(values: npt.ArrayLike | Mapping[str, float]) -> Command:
    """Raw control command: ``MjData.ctrl`` in each actuator's own units, for any actuator kind.

    For robots whose actuators differ in kind (arm motors and a gripper's position actuator) or
    take neither a force nor a target (muscle activation in [0, 1]); a full vector (nu,) or a
    name mapping. The typed commands above are checked against the actuator's kind; this one
    says explicitly that the caller knows each actuator's units.
    """
    return _make(CommandKind.CTRL, values)


def joint_actuators(actuators: Mapping[str, ActuatorInfo]) -> dict[str, ActuatorInfo]:
    """The actuator a joint name addresses in a command: the first actuator driving that joint."""
    return {a.joint: a for a in reversed(list(actuators.values())) if a.joint}


def actuators_named(
    names: Sequence[str],
    actuators: Mapping[str, ActuatorInfo],
    by_joint: Mapping[str, ActuatorInfo],
    kind: str = "command",
) -> list[ActuatorInfo]:
    """The actuators a command's names address: an actuator's name, or the name of its joint.

    Called once per command layout (the simulator caches the result), not per step.

    Args:
        names: Actuator or actuated-joint names, one per command value.
        actuators: The robot's actuators by name.
        by_joint: Actuators by the joint they drive (``joint_actuators``); an actuator name wins
            over a joint of the same name.
        kind: What is resolved, for messages (e.g. "torque command").

    Returns:
        One actuator per name, in the order of ``names``.

    Raises:
        UnknownNameError: A name that is neither an actuator nor an actuated joint.
        CommandError: Two names addressing the same actuator (e.g. a joint and its actuator):
            one of the two values would be dropped silently.
    """
    out: list[ActuatorInfo] = []
    first_name: dict[str, str] = {}
    for name in names:
        info = actuators.get(name) or by_joint.get(name)
        if info is None:
            known = list(actuators) + [j for j in by_joint if j not in actuators]
            raise UnknownNameError("actuator or actuated joint", name, known)
        if info.name in first_name:
            raise CommandError(
                f"The {kind} names actuator {info.name!r} twice: as {_as_named(first_name[info.name], info)} "
                f"and as {_as_named(name, info)}; one value would be dropped. Name each actuator once."
            )
        first_name[info.name] = name
        out.append(info)
    return out


def _as_named(name: str, info: ActuatorInfo) -> str:
    return f"{name!r}" if name == info.name else f"{name!r} (its joint)"


def kind_mismatch(kind: CommandKind, actuators: Sequence[ActuatorInfo]) -> str | None:
    """Why a ``kind`` command cannot drive ``actuators`` (those of another kind), or None if it can.

    The one message for the mistake, whether the simulator meets it at a step or a controller
    at construction.
    """
    wrong = [] if kind is CommandKind.CTRL else [a for a in actuators if a.kind != kind.value]
    if not wrong:
        return None
    listing = ", ".join(f"{a.name} ({a.kind})" for a in wrong[:6])
    return (f"A {kind.value} command cannot drive {listing}: the actuator kind differs. "
            f"Send a command of the actuator's kind, a raw ctrl command (mbctl.robots.commands.ctrl: "
            f"each actuator's own units), or convert the model's actuators "
            f"(e.g. mbctl.robots.edits.position_to_motor for torque control).")
