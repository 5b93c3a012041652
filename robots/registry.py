"""Known robots and ``load_robot``: the one entry point from a name or an MJCF path to a Robot."""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin

from mbctl.robots.exceptions import ModelFileError, ModelNotFoundError, RobotError, UnknownNameError
from mbctl.robots.joint_pairing import pair_joints
from mbctl.robots.menagerie import resolve_menagerie_dir
from mbctl.robots.model_files import ModelSource, compile_spec, load_mj_spec, load_pin_model
from mbctl.robots.model_pair import Robot
from mbctl.robots.model_size import check_model_file_size, check_robot_dof
from mbctl.robots.names import mj_name
from mbctl.robots.pin_from_mj import pin_model_from_mj
from mbctl.robots.scene import robot_bodies
from mbctl.robots.scene_match import robot_in_scene

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
    joint_map: Mapping[str, str] | None = None,
    floating_base: bool | None = None,
) -> Robot:
    """Load a known robot by name, or any MJCF robot by path, as a checked model pair.

    Args:
        name_or_path: A known robot name (see ``KNOWN_ROBOTS``) or an MJCF robot file.
        scene: A scene file for MuJoCo that includes the robot (default: the robot file, or the
            known robot's scene). Bodies the scene adds (a floor, a wall, a mocap target, a free
            box) are scene, not robot: see ``roots``. The scene's robot must be the robot
            file's (``robots/scene_match.py``); its root bodies select it in the scene.
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
        joint_map: With the parser: ``{joint in the Pinocchio file: joint of the plant}`` for
            joints named differently. Joints are paired by name and put in the plant's order
            (``robots/joint_pairing.py``); the edits are recorded in ``source.edits``.
        floating_base: With the parser: True adds a free flyer to a fixed-base file, False never
            does, None (default) adds one when the plant's robot has a free root joint.

    Raises:
        UnknownNameError: Not a known robot and not an existing file; a joint map name that
            neither model has.
        ModelNotFoundError: A Menagerie model that is not on this machine.
        ModelFileError: A file that is missing, corrupt, or fails its hash.
        SceneMismatchError: The scene's robot is not the robot file's.
        ModelMismatchError: The two engines disagree.
        RobotError: ``joint_map`` or ``floating_base`` without the parser.
    """
    key = str(name_or_path)
    user_scene = scene is not None
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
    if pin_model_file:
        analytic = "parser"
    if analytic != "parser" and (joint_map or floating_base is not None):
        raise RobotError(
            "joint_map (--joint-map) and floating_base (--floating-base) pair a Pinocchio model read "
            "from a file with the plant: use them with pin_model_file (--pin-model) or analytic='parser'"
        )
    check_model_file_size(scene_file)
    spec = load_mj_spec(scene_file)
    edits: tuple[str, ...] = ()
    if gravity is True and gravity_on is not None:
        spec.option.gravity = np.array(gravity_on)
        edits = (f"gravity set to {gravity_on} m/s^2",)
    elif gravity is False:
        spec.option.gravity = np.zeros(3)
        edits = ("gravity set to zero",)
    mj_model = compile_spec(spec, scene_file)
    if user_scene and scene_file != robot_file:
        roots = robot_in_scene(robot_file, scene_file, mj_model, roots)
    pin_file = Path(pin_model_file).expanduser().resolve() if pin_model_file else robot_file
    pin_model: pin.Model | None = None  # built by Robot from the compiled MjModel (robots/pin_from_mj.py)
    if analytic == "parser":
        parsed = load_pin_model(pin_file)
        check_robot_dof(parsed.nv, name)
        plant = pin_model_from_mj(mj_model, robot_bodies(mj_model, roots))
        unnamed = [mj_name(mj_model, mujoco.mjtObj.mjOBJ_JOINT, j)
                   for j in range(mj_model.njnt) if not mj_model.joint(j).name]
        pairing = pair_joints(parsed, plant, joint_map, floating_base, unnamed)
        pin_model = pairing.model
        if pin_model_file:
            edits = (*edits, f"Pinocchio model from {pin_file}")
        edits = (*edits, *pairing.edits)
    source = ModelSource(name, pin_file, scene_file, origin, edits, analytic, tuple(roots))
    return Robot(source, pin_model, spec, check=check, mj_model=mj_model)


def _existing_file(path: str | os.PathLike, role: str) -> Path:
    """``path`` resolved; ModelFileError naming it when it is not a file."""
    out = Path(path).expanduser().resolve()
    if not out.is_file():
        raise ModelFileError(f"The {role} file {str(path)!r} does not exist.")
    return out
