"""Robot descriptions and the model pair (Pinocchio model + MuJoCo model) with conventions."""

from mbctl.robots import mjlog  # noqa: F401 - MuJoCo's log file stays out of the cwd
from mbctl.robots.collision import CollisionPair, GeomPairs, resolve_pairs
from mbctl.robots.command_binding import CommandBinder
from mbctl.robots.commands import Command, CommandKind, ctrl, position_target, torque, velocity_target
from mbctl.robots.conventions import (
    JointLayout,
    StateConverter,
    VelocityMaps,
    quat_wxyz_to_xyzw,
    quat_xyzw_to_wxyz,
    quat_xyzw_yaw,
)
from mbctl.robots.edits import position_to_motor, weld_base
from mbctl.robots.exceptions import (
    JointMapError,
    ModelFileError,
    ModelMismatchError,
    ModelNotFoundError,
    RobotError,
    SceneMismatchError,
    StateError,
    UnknownNameError,
)
from mbctl.robots.interface import ImuSpec, RobotInterface, RobotState
from mbctl.robots.model_pair import ModelSource, Robot
from mbctl.robots.names import ActuatorInfo, SensorInfo
from mbctl.robots.plant_report import LinkReport, PlantReport, SafetyReport, TimingReport
from mbctl.robots.registry import KNOWN_ROBOTS, load_robot

__all__ = [
    "KNOWN_ROBOTS",
    "ActuatorInfo",
    "CollisionPair",
    "GeomPairs",
    "Command",
    "CommandKind",
    "ctrl",
    "JointLayout",
    "JointMapError",
    "ModelFileError",
    "ModelMismatchError",
    "ModelNotFoundError",
    "ModelSource",
    "Robot",
    "RobotError",
    "RobotInterface",
    "CommandBinder",
    "ImuSpec",
    "LinkReport",
    "PlantReport",
    "SafetyReport",
    "TimingReport",
    "RobotState",
    "SceneMismatchError",
    "SensorInfo",
    "StateConverter",
    "StateError",
    "UnknownNameError",
    "VelocityMaps",
    "load_robot",
    "position_target",
    "position_to_motor",
    "quat_wxyz_to_xyzw",
    "quat_xyzw_to_wxyz",
    "quat_xyzw_yaw",
    "resolve_pairs",
    "torque",
    "velocity_target",
    "weld_base",
]

# The cross-check is the subpackage mbctl.robots.crosscheck (``from mbctl.robots.crosscheck
# import crosscheck``): re-exporting its function here would shadow the subpackage's name.

