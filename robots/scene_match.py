"""Does a scene hold the robot file's robot? The check behind ``load_robot(robot_file, scene)``.

A scene file is MuJoCo's plant: it includes a robot file and adds a floor, props, lights. Nothing
in MJCF ties the scene to the robot file named beside it, so a scene of another robot (or of
another variant: without the hand, with an arm) would load and cross-check that robot under the
robot file's name. Here the robot file is compiled on its own, its robot selected as usual
(``robots/scene.py``: the trees its actuators drive, or ``roots``), and the scene's trees of the
same root bodies must be that robot: the same bodies and joints (names, kinds, parents), the
same joint axes and the same inertias, at round-off (``robots/model_diff.py``). Otherwise a
``SceneMismatchError`` names the first difference.

The robot file's root bodies also select the robot in the scene, so props the scene adds (a free
box, another passive mechanism) stay scene even without actuators.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import mujoco

from mbctl.robots.exceptions import SceneMismatchError, UnknownNameError
from mbctl.robots.model_diff import model_differences
from mbctl.robots.model_files import compile_spec, load_mj_spec
from mbctl.robots.pin_from_mj import pin_model_from_mj
from mbctl.robots.scene import robot_bodies


def robot_in_scene(
    robot_file: Path, scene_file: Path, scene: mujoco.MjModel, roots: Sequence[str] = ()
) -> tuple[str, ...]:
    """Check that ``scene`` holds the robot of ``robot_file``; the root bodies that select it.

    Args:
        robot_file: The robot's MJCF file (it must compile on its own).
        scene_file: The scene's file, for messages.
        scene: The compiled scene.
        roots: Body names whose trees are the robot (default: the robot file's actuated trees).

    Returns:
        The names of the robot's root bodies (children of the world), in the robot file's
        order, to select the robot in the scene; ``roots`` itself when a root body has no name.

    Raises:
        SceneMismatchError: The scene lacks a root body of the robot, or its robot differs from
            the robot file's (the first difference is named, with both values).
        ModelFileError: The robot file does not parse or compile on its own.
    """
    own = compile_spec(load_mj_spec(robot_file), robot_file)
    what = f"The scene {str(scene_file)!r} does not hold the robot of {str(robot_file)!r}"
    try:
        own_bodies = robot_bodies(own, roots)
    except UnknownNameError as exc:
        raise SceneMismatchError(
            f"{what}: the root body {exc.name!r} is not a body of the robot file. With a scene, the "
            "robot is the robot file's: give roots among its bodies."
        ) from None
    tops = [b for b in sorted(own_bodies) if int(own.body_parentid[b]) == 0]
    names = tuple(mujoco.mj_id2name(own, mujoco.mjtObj.mjOBJ_BODY, b) or "" for b in tops)
    if not all(names):
        names = tuple(roots)
    missing = [n for n in names if mujoco.mj_name2id(scene, mujoco.mjtObj.mjOBJ_BODY, n) < 0]
    if missing:
        raise SceneMismatchError(
            f"{what}: it has no body {missing[0]!r}, a root body of the robot file's robot. Give a "
            "scene that includes this robot file, or load the scene's own robot file."
        )
    scene_robot = robot_bodies(scene, names)
    differences = model_differences(
        pin_model_from_mj(own, own_bodies),
        pin_model_from_mj(scene, scene_robot),
        ("the robot file", "the scene"),
        bodies=True,
    )
    if differences:
        more = f" (and {len(differences) - 1} more differences)" if len(differences) > 1 else ""
        raise SceneMismatchError(f"{what}: {differences[0]}{more}.")
    return names
