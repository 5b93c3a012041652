"""Robot descriptions and the model pair (Pinocchio model + MuJoCo model) with conventions."""

from mbctl.robots.conventions import (
    JointLayout,
    StateConverter,
    quat_wxyz_to_xyzw,
    quat_xyzw_to_wxyz,
)
from mbctl.robots.exceptions import (
    ModelFileError,
    ModelMismatchError,
    ModelNotFoundError,
    RobotError,
    StateError,
    UnknownNameError,
)
from mbctl.robots.model_pair import ModelSource, Robot
from mbctl.robots.names import ActuatorInfo, SensorInfo
from mbctl.robots.registry import KNOWN_ROBOTS, load_robot

__all__ = [
    "KNOWN_ROBOTS",
    "ActuatorInfo",
    "JointLayout",
    "ModelFileError",
    "ModelMismatchError",
    "ModelNotFoundError",
    "ModelSource",
    "Robot",
    "RobotError",
    "SensorInfo",
    "StateConverter",
    "StateError",
    "UnknownNameError",
    "load_robot",
    "quat_wxyz_to_xyzw",
    "quat_xyzw_to_wxyz",
]

# The cross-check is the subpackage mbctl.robots.crosscheck (``from mbctl.robots.crosscheck
# import crosscheck``): re-exporting its function here would shadow the subpackage's name.

