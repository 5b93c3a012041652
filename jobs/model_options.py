"""The options every simulating job shares: a hidden truth on the plant, and the controller's model.

``--payload KG@BODY[:X,Y,Z]`` fixes a point mass to a body of the plant (offset in the body
frame [m]); ``--plant-error PCT`` scales the plant's link masses and inertias (as
``--model-error`` scales the controller's model). The controller never sees either: they are the
truth an identification has to find. ``--controller-model FILE.xml`` gives the controller its
model from a file (e.g. an ``identified.xml``) while the plant stays the robot's own; a file
whose joints are not the robot's (by name and order) is refused.

A job calls :func:`build_models` once on the robot it loaded (after its own edits, such as
torque motors) and runs the simulator on ``models.plant`` and its controller on
``models.controller_model``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pinocchio as pin

from mbctl.exceptions import ToolkitError
from mbctl.robots.edits import add_payload, check_payload_offset, scale_link_masses
from mbctl.robots.exceptions import RobotError
from mbctl.robots.model_pair import Robot
from mbctl.robots.registry import load_robot


class ModelOptionError(ToolkitError, ValueError):
    """A malformed ``--payload``, a bad ``--plant-error``, or a controller model of another robot."""


@dataclass(frozen=True)
class Payload:
    """A point mass on a body of the plant.

    Attributes:
        mass_kg: Mass [kg].
        body: Body it is fixed to.
        offset_m: Position (3,) [m] in the body frame.
    """

    mass_kg: float
    body: str
    offset_m: tuple[float, float, float] = (0.0, 0.0, 0.0)


def parse_payload(text: str) -> Payload:
    """``"KG@BODY[:X,Y,Z]"`` -> Payload (``"2.0@torso_link:0.05,0,0.25"``).

    Raises:
        ModelOptionError: Not of that form, a mass that is not > 0, or an offset of other than 3
            finite numbers or farther than ``MAX_PAYLOAD_OFFSET_M`` from the body.
    """
    form = "KG@BODY[:X,Y,Z] (e.g. 2.0@torso_link:0.05,0,0.25)"
    mass_text, at, rest = text.partition("@")
    body, _, offset_text = rest.partition(":")
    try:
        mass = float(mass_text)
    except ValueError:
        raise ModelOptionError(f"--payload must look like {form}; the mass {mass_text!r} is not a number "
                               f"(got {text!r})") from None
    if not at or not body.strip():
        raise ModelOptionError(f"--payload must look like {form}; got {text!r}")
    if not (math.isfinite(mass) and mass > 0):
        raise ModelOptionError(f"--payload mass must be > 0 kg; got {mass_text!r}")
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    if offset_text:
        try:
            values = [float(x) for x in offset_text.split(",")]
        except ValueError:
            values = []
        if len(values) != 3 or not all(math.isfinite(v) for v in values):
            raise ModelOptionError(f"--payload offset must be X,Y,Z in metres (body frame); got "
                                   f"{offset_text!r}")
        offset = (values[0], values[1], values[2])
        try:
            check_payload_offset(offset)
        except RobotError as exc:
            raise ModelOptionError(f"--payload {text!r}: {exc}") from None
    return Payload(mass, body.strip(), offset)


@dataclass(frozen=True)
class ModelOptions:
    """What ``--payload``, ``--plant-error`` and ``--controller-model`` ask for.

    Attributes:
        payload: ``KG@BODY[:X,Y,Z]`` or None.
        plant_error: The plant's link masses and inertias off by this [%].
        controller_model: MJCF file of the controller's model, or None (the robot's own).
    """

    payload: str | None = None
    plant_error: float = 0.0
    controller_model: str | None = None

    def __post_init__(self) -> None:
        if self.payload is not None:
            parse_payload(self.payload)
        if not (math.isfinite(self.plant_error) and self.plant_error > -100):
            raise ModelOptionError(f"--plant-error must be a finite percentage > -100; got "
                                   f"{self.plant_error}")
        if self.controller_model is not None and not Path(self.controller_model).expanduser().is_file():
            raise ModelOptionError(f"--controller-model {self.controller_model!r} is not a file; give the "
                                   "MJCF of the controller's model (e.g. an identified.xml)")

    @property
    def hidden(self) -> bool:
        """The plant differs from the robot's own model."""
        return self.payload is not None or self.plant_error != 0.0


@dataclass(frozen=True)
class Models:
    """The plant a job simulates and the model its controller uses.

    Attributes:
        plant: The plant (the robot, with the hidden truth applied).
        controller: The robot whose Pinocchio model the controller uses (the robot itself, or the
            ``--controller-model`` file with the job's edits).
        options: The options they were built from.
    """

    plant: Robot
    controller: Robot
    options: ModelOptions

    @property
    def controller_model(self) -> pin.Model:
        """The controller's Pinocchio model."""
        return self.controller.pin_model

    def section(self) -> dict[str, Any]:
        """What the report records: the plant's hidden edits and where the controller's model came from."""
        return {"payload": self.options.payload, "plant_error_pct": self.options.plant_error,
                "controller_model": str(self.controller.source.scene_file) if self.options.controller_model
                else "the robot's own"}


def build_models(robot: Robot, options: ModelOptions, edit: Callable[[Robot], Robot] | None = None) -> Models:
    """The plant and the controller's robot for ``options``.

    Args:
        robot: The robot as the job loaded it, after its own edits (e.g. torque motors).
        options: The plant options.
        edit: The job's edits, applied to a ``--controller-model`` robot too (so it has the same
            actuators and sites as ``robot``).

    Raises:
        ModelOptionError: A controller model whose joints differ from the robot's.
        UnknownNameError: A payload on a body the robot does not have.
        RobotError: A payload heavier than ``MAX_PAYLOAD_MASS_RATIO`` times the robot.
        ModelFileError: A controller model MuJoCo or Pinocchio cannot read.
    """
    plant = robot
    if options.payload is not None:
        p = parse_payload(options.payload)
        plant = add_payload(plant, p.mass_kg, p.body, p.offset_m)
    if options.plant_error:
        plant = scale_link_masses(plant, 1.0 + options.plant_error / 100.0)
    controller = robot
    if options.controller_model is not None:
        controller = load_robot(Path(options.controller_model).expanduser())
        if edit is not None:
            controller = edit(controller)
        mine, theirs = list(robot.joints), list(controller.joints)
        if mine != theirs:
            missing = [j for j in mine if j not in theirs]
            extra = [j for j in theirs if j not in mine]
            raise ModelOptionError(
                f"--controller-model {options.controller_model} has joints that are not {robot.name!r}'s: "
                f"missing {missing[:5]}, extra {extra[:5]}"
                + (" (same names, another order)" if not missing and not extra else "")
                + "; give a model of the same robot (e.g. the identified.xml of its log)")
        if (controller.nq, controller.nv) != (robot.nq, robot.nv):
            raise ModelOptionError(f"--controller-model has nq={controller.nq}, nv={controller.nv}; the "
                                   f"robot has nq={robot.nq}, nv={robot.nv}")
        # gravity is the plant's environment, not the model's: the controller assumes the plant's
        controller.pin_model.gravity = robot.pin_model.gravity
    return Models(plant, controller, options)


def models_line(section: dict[str, Any]) -> str:
    """One summary line: what the plant hides and which model the controller uses."""
    hidden = []
    if section["payload"]:
        hidden.append(f"payload {section['payload']}")
    if section["plant_error_pct"]:
        hidden.append(f"link masses {section['plant_error_pct']:+g} %")
    return (f"plant: {', '.join(hidden) or 'the robot as modelled'}; controller model: "
            f"{section['controller_model']}")
