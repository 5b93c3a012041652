"""The MuJoCo backend: simulator, recorder and execution reports."""

from mbctl.robots.commands import Command, CommandKind, position_target, torque, velocity_target
from mbctl.robots.interface import RobotInterface, RobotState
from mbctl.sim.exceptions import SimError, SimulationDiverged
from mbctl.sim.link import LinkedSimulator, LinkSpec
from mbctl.sim.simulator import Simulator

__all__ = [
    "Command",
    "CommandKind",
    "LinkSpec",
    "LinkedSimulator",
    "RobotInterface",
    "RobotState",
    "SimError",
    "SimulationDiverged",
    "Simulator",
    "position_target",
    "torque",
    "velocity_target",
]
