"""The plant check of ``mbctl ik``: the IK's answer measured by MuJoCo, at the targets and on the body.

The pose (Pinocchio convention) is written into a scratch ``MjData`` of ``robot.mj_model``
(``robot.plant_qpos``, the scene's coordinates at ``qpos0``) and only ``mj_kinematics`` runs
(never a step). Measured there:

* every position target (held and target frames; relative targets in their reference frame) and
  the CoM of the robot (its bodies' masses at ``xipos``; not ``subtree_com[0]``, which is the whole
  plant's and moves with a scene's props and mocap targets): ``plant_residual_m``;
* every orientation target (held, base, oriented frames): ``plant_residual_rad``;
* the collision pairs at EVERY configuration the IK visited (``IKResult.q_path``), with
  ``mj_geomDistance``: the smallest distance on the path, its pair and its step.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pinocchio as pin

from mbctl.control.ik import WholeBodyIK, mujoco_frame_type
from mbctl.control.tasks import TaskResidual
from mbctl.robots.collision import GeomPairs, closest_pairs
from mbctl.robots.model_pair import Robot
from mbctl.robots.plant_kinematics import PlantKinematics
from mbctl.robots.scene import bodies_com


class PlantFrames(NamedTuple):
    """Frames measured on the MuJoCo plant (``mj_kinematics``, never stepped).

    Attributes:
        positions: p_WF (3,) [m] by frame, world frame.
        rotations: R_WF (3, 3) by frame, world frame.
        com: Centre of mass p_WC (3,) [m] of the robot (not of the scene), world frame.
    """

    positions: dict[str, np.ndarray]
    rotations: dict[str, np.ndarray]
    com: np.ndarray


class PlantResiduals(NamedTuple):
    """How far the plant (MuJoCo) is from each target at the IK's pose.

    Judged by the IK's own rule: ``converged(plant.task_residuals(), tolerance)``
    (:func:`mbctl.control.tasks.residuals.converged`).

    Attributes:
        position_m: Distance [m] from each position target (frames; the CoM as ``"com"``).
        orientation_rad: Rotation angle [rad] from each orientation target.
    """

    position_m: dict[str, float]
    orientation_rad: dict[str, float]

    def task_residuals(self) -> dict[str, TaskResidual]:
        """The measurements as task residuals, by frame (the CoM as ``"com"``), units in the fields."""
        positions, angles = self.position_m, self.orientation_rad
        names = [*positions, *(f for f in angles if f not in positions)]
        return {f: TaskResidual(position_m=positions.get(f), orientation_rad=angles.get(f)) for f in names}


def plant_frames(robot: Robot, q: np.ndarray, frames: tuple[str, ...]) -> PlantFrames:
    """Poses of ``frames`` and the robot's CoM from MuJoCo's own kinematics on a scratch ``MjData``.

    Args:
        robot: The model pair (its ``mj_model`` is read, never stepped).
        q: Configuration (nq,), Pinocchio convention (converted with ``robot.converter``).
        frames: MuJoCo sites or bodies.

    Raises:
        IKSetupError: A frame that is neither a site nor a body (the message lists them).
    """
    data = PlantKinematics(robot=robot).at(q)
    positions, rotations = {}, {}
    for frame in frames:
        if mujoco_frame_type(robot, frame) == "site":
            i = robot.site_id(frame)
            positions[frame], rotations[frame] = data.site_xpos[i].copy(), data.site_xmat[i].reshape(3, 3)
        else:
            i = robot.body_id(frame)
            positions[frame], rotations[frame] = data.xpos[i].copy(), data.xmat[i].reshape(3, 3)
    return PlantFrames(positions, {f: R.copy() for f, R in rotations.items()},
                       bodies_com(robot.mj_model, data, robot.robot_body_ids))


def plant_residuals(robot: Robot, ik: WholeBodyIK, q: np.ndarray) -> PlantResiduals:
    """Residuals of the IK's targets measured on the MuJoCo plant at ``q`` (nq,), Pinocchio."""
    targets = ik.targets()
    frames = {*targets, *(t.reference for t in targets.values() if t.reference is not None)}
    plant = plant_frames(robot, q, tuple(sorted(frames)))
    positions, angles = {}, {}
    for frame, target in targets.items():
        R, p = plant.rotations[frame], plant.positions[frame]
        if target.reference is not None:  # the pose in the reference frame
            R_WR, p_WR = plant.rotations[target.reference], plant.positions[target.reference]
            R, p = R_WR.T @ R, R_WR.T @ (p - p_WR)
        if target.has_position:
            positions[frame] = float(np.linalg.norm(p - target.position))
        if target.has_orientation:
            angles[frame] = float(np.linalg.norm(pin.log3(target.rotation.T @ R)))
    com_target = ik.com_target
    if com_target is not None:
        axes = 3 if ik.config.com_height else 2
        positions["com"] = float(np.linalg.norm(plant.com[:axes] - com_target[:axes]))
    return PlantResiduals(positions, angles)


class PathCollisions(NamedTuple):
    """The collision pairs along the IK's path, as MuJoCo measures them.

    Attributes:
        distances_m: The closest pair's signed distance [m] at each configuration (negative:
            penetration), the start first.
        pairs: The closest pair's label at each configuration.
        n_pairs: How many geom pairs were measured at each configuration.
    """

    distances_m: np.ndarray
    pairs: tuple[str, ...]
    n_pairs: int

    @property
    def min_distance_m(self) -> float:
        """The smallest distance [m] on the whole path."""
        return float(self.distances_m.min())

    @property
    def closest_step(self) -> int:
        """The path index (0: the start) where the smallest distance occurs."""
        return int(np.argmin(self.distances_m))

    @property
    def closest_pair(self) -> str:
        """The pair at the smallest distance on the path."""
        return self.pairs[self.closest_step]

    def clear_of(self, min_distance_m: float) -> bool:
        """Every configuration keeps every pair at or above ``min_distance_m`` [m]."""
        return bool(np.all(self.distances_m >= min_distance_m))


def path_collisions(robot: Robot, pairs: GeomPairs, q_path: np.ndarray) -> PathCollisions:
    """The closest pair at every configuration of ``q_path`` (N, nq), Pinocchio convention."""
    closest = closest_pairs(robot, q_path, pairs)
    distances = np.array([c.distance_m for c in closest])
    return PathCollisions(distances, tuple(c.pair for c in closest), len(pairs))
