"""Errors raised while resolving, loading and converting robot models."""

from __future__ import annotations

from collections.abc import Iterable

from mbctl.exceptions import ToolkitError, close_matches, unknown_name_message


class RobotError(ToolkitError):
    """Base class of robot-model errors."""


class UnknownNameError(RobotError, KeyError):
    """A joint, actuator, site, body, sensor, keyframe or robot name the model does not have.

    Attributes:
        kind: What was looked up ("joint", "actuator", ...).
        name: The unknown name.
        suggestions: The closest known names, best first.
    """

    def __init__(self, kind: str, name: str, known: Iterable[str]):
        known = list(known)
        self.kind = kind
        self.name = name
        self.suggestions = close_matches(name, known)
        self.message = unknown_name_message(kind, name, known)
        super().__init__(self.message)

    def __str__(self) -> str:  # KeyError would quote the message
        return self.message


class ModelFileError(RobotError):
    """A model file that is missing, fails to parse, or fails its SHA-256 manifest."""


class ModelNotFoundError(RobotError):
    """A third-party model (e.g. the Menagerie G1) that cannot be found on this machine."""


class ModelMismatchError(RobotError):
    """The Pinocchio and MuJoCo models of one robot disagree (names, sizes, mass, armature)."""


class SceneMismatchError(ModelMismatchError):
    """A scene whose robot is not the robot file's robot (other trees, joints or inertias)."""


class JointMapError(RobotError, ValueError):
    """A joint map (Pinocchio file joint -> plant joint) that is malformed or maps a name twice."""


class StateError(RobotError, ValueError):
    """A configuration or velocity vector with the wrong shape or non-finite entries."""


class CommandError(RobotError, ValueError):
    """A command the robot cannot take: wrong kind, shape or names, or non-finite values."""


class CommandOutOfRange(CommandError):
    """A command outside an actuator's ctrlrange, where out-of-range commands are rejected."""


class CollisionPairError(RobotError, ValueError):
    """A collision pair that is malformed or leaves no geom pair to keep apart."""
