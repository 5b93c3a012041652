"""Known robots and ``load_robot``: the one entry point from a name or an MJCF path to a Robot."""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from mbctl.robots.exceptions import ModelFileError, ModelNotFoundError, UnknownNameError
from mbctl.robots.menagerie import resolve_menagerie_dir
from mbctl.robots.model_pair import ModelSource, Robot, load_mj_spec, load_pin_model
from mbctl.robots.model_size import check_model_file_size, check_robot_dof

ASSETS = Path(__file__).parent / "assets"

#: Gravity [m/s^2] of the 2-link arm when switched on: in the arm's x-y plane, along -y
#: (a wall-mounted arm), so that gravity compensation matters.
TWO_LINK_GRAVITY = (0.0, -9.81, 0.0)


@dataclass(frozen=True)
class KnownRobot:
    """A robot mbctl knows by name.

    Attributes:
        name: Name used on the command line and in ``load_robot``.
        description: One line for ``mbctl robots``.
        origin: Where the model comes from.
        locate: Returns (robot file, scene file, provenance) — may resolve or download.
        gravity_on: Gravity [m/s^2] used when ``load_robot(..., gravity=True)``; None keeps the file's.
    """

    name: str
    description: str
    origin: str
    locate: Callable[[str | os.PathLike | None], tuple[Path, Path, str]]
    gravity_on: tuple[float, float, float] | None = None


def _embedded(scene: str) -> Callable[[str | os.PathLike | None], tuple[Path, Path, str]]:
    def locate(_path: str | os.PathLike | None) -> tuple[Path, Path, str]:
        return ASSETS / "two_link_arm.xml", ASSETS / scene, f"embedded (mbctl/robots/assets/{scene})"

    return locate


def _locate_g1(path: str | os.PathLike | None) -> tuple[Path, Path, str]:
    directory = resolve_menagerie_dir("unitree_g1", path)
    return directory / "g1.xml", directory / "scene.xml", f"MuJoCo Menagerie unitree_g1 at {directory}"


KNOWN_ROBOTS: dict[str, KnownRobot] = {
    "two_link": KnownRobot(
        "two_link",
        "2-link planar arm, position actuators (MuJoCo internal PD)",
        "embedded: robots/assets/two_link.xml",
        _embedded("two_link.xml"),
        TWO_LINK_GRAVITY,
    ),
    "two_link_torque": KnownRobot(
        "two_link_torque",
        "2-link planar arm, torque motors",
        "embedded: robots/assets/two_link_torque.xml",
        _embedded("two_link_torque.xml"),
        TWO_LINK_GRAVITY,
    ),
    "g1": KnownRobot(
        "g1",
        "Unitree G1 humanoid, floating base, 29 position actuators",
        "MuJoCo Menagerie unitree_g1 (explicit path, $MENAGERIE_ROOT, or the mujoco-menagerie package)",
        _locate_g1,
    ),
}


#: The ways to build the analytic model (see ``load_robot``).
ANALYTIC = ("mujoco", "parser")


def load_robot(
    name_or_path: str | os.PathLike,
    scene: str | os.PathLike | None = None,
    *,
    gravity: bool | None = None,
    model_dir: str | os.PathLike | None = None,
    pin_model_file: str | os.PathLike | None = None,
    check: bool = True,
    analytic: str = "mujoco",
    roots: Sequence[str] = (),
) -> Robot:
    """Load a known robot by name, or any MJCF robot by path, as a checked model pair.

    Args:
        name_or_path: A known robot name (see ``KNOWN_ROBOTS``) or an MJCF robot file.
        scene: A scene file for MuJoCo that includes the robot (default: the robot file, or the
            known robot's scene). Bodies the scene adds (a floor, a wall, a mocap target, a free
            box) are scene, not robot: see ``roots``.
        gravity: None keeps the model's gravity; True switches on the robot's gravity (for the
            2-link arm: -y in its plane); False sets gravity to zero in both engines.
        model_dir: Explicit model directory for Menagerie robots (overrides $MENAGERIE_ROOT).
        pin_model_file: Build the Pinocchio side from this file instead (MJCF or URDF).
        check: Run the load-time agreement check (disable only to cross-check a different model).
        analytic: "mujoco" (default) builds the Pinocchio model from MuJoCo's compiled model, which
            has resolved defaults, frames, includes, several joints per body, several trees and
            mesh inertia; "parser" uses Pinocchio's MJCF parser on the robot file (the independent
            path; ``pin_model_file`` implies it).
        roots: Body names whose trees are the robot; default: the trees whose joints the
            actuators drive (``robots/scene.py``). Everything else in the plant is scene.

    Raises:
        UnknownNameError: Not a known robot and not an existing file.
        ModelNotFoundError: A Menagerie model that is not on this machine.
        ModelFileError: A file that is missing, corrupt, or fails its hash.
        ModelMismatchError: The two engines disagree.
    """
    key = str(name_or_path)
    if key in KNOWN_ROBOTS:
        known = KNOWN_ROBOTS[key]
        robot_file, scene_file, origin = known.locate(model_dir)
        if scene is not None:  # the user's scene (it includes the robot file itself)
            scene_file = _existing_file(scene, "scene")
            origin = f"{origin}, scene {scene_file}"
        name = key
        gravity_on = known.gravity_on
    else:
        path = Path(name_or_path).expanduser()
        if not path.suffix and not path.exists():
            raise UnknownNameError("robot", key, KNOWN_ROBOTS)
        if not path.is_file():
            raise ModelNotFoundError(
                f"{key!r} is neither a known robot ({', '.join(KNOWN_ROBOTS)}) nor an existing file."
            )
        robot_file = path.resolve()
        scene_file = _existing_file(scene, "scene") if scene is not None else robot_file
        origin = f"user file {robot_file}"
        name = robot_file.stem
        gravity_on = None
    if analytic not in ANALYTIC:
        raise UnknownNameError("analytic model path", analytic, ANALYTIC)
    check_model_file_size(scene_file)
    spec = load_mj_spec(scene_file)
    pin_file = Path(pin_model_file).expanduser().resolve() if pin_model_file else robot_file
    if pin_model_file or analytic == "parser":
        analytic = "parser"
        parsed = load_pin_model(pin_file)
        check_robot_dof(parsed.nv, name)
        pin_model: pin.Model | None = parsed
    else:
        pin_model = None  # built by Robot from the compiled MjModel (robots/pin_from_mj.py)
    edits: tuple[str, ...] = ()
    if gravity is True and gravity_on is not None:
        spec.option.gravity = np.array(gravity_on)
        edits = (f"gravity set to {gravity_on} m/s^2",)
    elif gravity is False:
        spec.option.gravity = np.zeros(3)
        edits = ("gravity set to zero",)
    if pin_model_file:
        edits = (*edits, f"Pinocchio model from {pin_file}")
    source = ModelSource(name, pin_file, scene_file, origin, edits, analytic, tuple(roots))
    return Robot(source, pin_model, spec, check=check)


def _existing_file(path: str | os.PathLike, role: str) -> Path:
    """``path`` resolved; ModelFileError naming it when it is not a file."""
    out = Path(path).expanduser().resolve()
    if not out.is_file():
        raise ModelFileError(f"The {role} file {str(path)!r} does not exist.")
    return out
