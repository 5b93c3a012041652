"""The whole-body IK task set on mink (``mink.solve_ik`` over the MuJoCo model): the "mink" backend.

The same task set as :class:`~mbctl.control.ik.whole_body.QPWholeBodyIK` (see that module for the
task set and where the two QPs differ), built from mink's own tasks and limits on
``robot.mj_model``; frames are MuJoCo sites or bodies. Collision pairs go to mink's
``CollisionAvoidanceLimit`` as the geom pairs our backend resolved (checked to be the same set
after mink's own filtering). mink solves one weighted level: a task set with priorities is
refused. States are converted with the model pair's ``StateConverter`` (MuJoCo's free-joint
linear velocity is in the world frame, Pinocchio's in the base frame), so the public ``q`` and
``v`` are Pinocchio's.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt

from mbctl.control.exceptions import IKSetupError
from mbctl.control.ik.whole_body import WholeBodyIK, joint_speeds, mujoco_frame_type
from mbctl.robots.model_pair import Robot


class MinkWholeBodyIK(WholeBodyIK):
    """The same task set on mink (MuJoCo model); limits built once.

    Attributes:
        configuration: ``mink.Configuration`` on ``robot.mj_model``.
        tasks: mink tasks by role (as in :class:`QPWholeBodyIK`).
        limits: mink limits (configuration, joint velocity, free-joint velocity).
    """

    backend = "mink"

    def _build(self) -> None:
        try:
            import mink
        except ImportError:
            raise IKSetupError("backend 'mink' needs the mink package (pip install mink); "
                               "or use backend 'qp'") from None
        self._mink = mink
        cfg, m = self.config, self.robot.mj_model
        if len(cfg.levels) > 1:
            raise IKSetupError(f"backend 'mink' solves one weighted level; this task set has "
                               f"{len(cfg.levels)} priority levels: use backend 'qp'")
        if not self.robot.covers_plant:  # mink's configuration is the whole plant's qpos
            raise IKSetupError(
                f"backend 'mink' cannot solve for {self.robot.name!r}: its plant has {m.nq - self.robot.nq} "
                "coordinates of scene bodies (free objects) that mink would move with the robot; use "
                "backend 'qp'"
            )
        self.configuration = mink.Configuration(m)
        self._types = {f: mujoco_frame_type(self.robot, f) for f in cfg.frames}
        self.tasks: dict[str, Any] = {}  # mink task types differ in their target setters
        for frame in cfg.held_frames:
            self.tasks[frame] = mink.FrameTask(frame, self._types[frame], cfg.held_position_cost,
                                               cfg.held_orientation_cost, lm_damping=cfg.lm_damping)
        for frame in cfg.target_frames:
            orientation = cfg.target_orientation_cost if frame in cfg.oriented_frames else 0.0
            reference = cfg.reference_of.get(frame)
            if reference is None:
                self.tasks[frame] = mink.FrameTask(frame, self._types[frame], cfg.target_position_cost,
                                                   orientation, lm_damping=cfg.lm_damping)
            else:
                self.tasks[frame] = mink.RelativeFrameTask(
                    frame, self._types[frame], reference, mujoco_frame_type(self.robot, reference),
                    cfg.target_position_cost, orientation, lm_damping=cfg.lm_damping)
        if cfg.base_frame is not None:
            self.tasks[cfg.base_frame] = mink.FrameTask(cfg.base_frame, self._types[cfg.base_frame], 0.0,
                                                        cfg.base_orientation_cost)
        if cfg.com:
            _check_mink_com(self.robot)
            self.tasks["com"] = mink.ComTask(cost=[cfg.com_cost, cfg.com_cost, 0.0])
        self.tasks["posture"] = mink.PostureTask(m, cost=cfg.posture_cost)
        if cfg.damping_cost > 0.0:
            self.tasks["damping"] = mink.DampingTask(m, cost=cfg.damping_cost)
        self._task_list = list(self.tasks.values())
        self.limits: list[Any] = [mink.ConfigurationLimit(m, gain=cfg.joint_position_gain)]
        speeds = joint_speeds(self.robot, cfg)
        if speeds:
            self.limits.append(mink.VelocityLimit(m, speeds))
        if self.robot.has_floating_base:
            self.limits.append(mink.FreeJointVelocityLimit(m, cfg.base_max_linear_velocity,
                                                           cfg.base_max_angular_velocity))
        self.collision_limit: Any = None
        if self.collision_pairs is not None:
            ids = self.collision_pairs.ids
            self.collision_limit = mink.CollisionAvoidanceLimit(
                m, [([int(a)], [int(b)]) for a, b in ids], gain=cfg.collision_gain,
                minimum_distance_from_collisions=cfg.min_distance_m,
                collision_detection_distance=cfg.collision_detection_distance_m)
            if set(self.collision_limit.geom_id_pairs) != {(int(a), int(b)) for a, b in ids}:
                raise IKSetupError("mink's CollisionAvoidanceLimit dropped some of the resolved geom pairs; "
                                   "the two backends would not avoid the same pairs")
            self.limits.append(self.collision_limit)

    def update(self, q: npt.ArrayLike) -> None:
        """Set the configuration from ``q`` (nq,), Pinocchio convention."""
        self.configuration.update(self.robot.converter.q_pin_to_mj(q))

    @property
    def q(self) -> np.ndarray:
        """Current configuration (nq,), Pinocchio convention (a copy)."""
        return np.array(self.robot.converter.q_mj_to_pin(self.configuration.q))

    def frame_transform(self, frame: str) -> tuple[np.ndarray, np.ndarray]:
        """``(R_WF (3, 3), p_WF (3,) [m])`` at the current configuration (MuJoCo kinematics)."""
        X = self.configuration.get_transform_frame_to_world(frame, mujoco_frame_type(self.robot, frame))
        return X.rotation().as_matrix(), np.array(X.translation())

    def com(self) -> np.ndarray:
        """Centre of mass p_WC (3,) [m] of the robot's root subtree (what mink's ComTask uses)."""
        return np.array(self.configuration.data.subtree_com[1])

    def _push_frame_target(self, frame: str, R_XT: np.ndarray, p_XT: np.ndarray) -> None:
        mink = self._mink
        self.tasks[frame].set_target(
            mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(R_XT), np.array(p_XT)))

    def _push_com_target(self, p: np.ndarray) -> None:
        self.tasks["com"].set_target(np.array(p))

    def _push_posture_target(self, q: np.ndarray) -> None:
        self.tasks["posture"].set_target(self.robot.converter.q_pin_to_mj(q))

    def step_mj(self) -> np.ndarray:
        """One step at the current configuration: MuJoCo qvel-convention velocity (nv,)."""
        return self._mink.solve_ik(self.configuration, self._task_list, self.config.dt, self.solver,
                                   damping=self.config.damping, limits=self.limits)

    def step(self, q: npt.ArrayLike) -> np.ndarray:
        """One step at ``q`` (nq,, Pinocchio); returns ``v`` (nv,) in Pinocchio's convention."""
        self.update(q)
        return self.robot.converter.v_mj_to_pin(q, self.step_mj())

    def advance(self) -> float:
        """Solve one step at the current configuration, integrate it; its inf-norm [rad or m]."""
        v = self.step_mj()
        self.configuration.integrate_inplace(v, self.config.dt)
        return float(np.max(np.abs(v))) * self.config.dt


def _check_mink_com(robot: Robot) -> None:
    """Refuse a CoM task mink would get wrong: its ComTask is the subtree CoM of MuJoCo body 1.

    That is the robot's CoM exactly when body 1 is the root of the robot's only tree; other
    bodies of the scene (props, mocap targets, a floor body) elsewhere in the tree do not matter.

    Raises:
        IKSetupError: Body 1 is not the robot's (the scene puts another body before the robot),
            or the robot has several trees; the message names the body and ``"qp"``.
    """
    m = robot.mj_model
    roots = [b for b in robot.robot_body_ids if int(m.body_parentid[b]) == 0]
    first = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, 1)
    if roots != [1]:
        if 1 not in roots:
            why = (f"MuJoCo body 1 ({first!r}, {float(m.body_subtreemass[1]):.6g} kg) is not the robot's "
                   "(the scene puts another body before the robot)")
        else:
            why = f"the robot has {len(roots)} trees and body 1's subtree is only one of them"
        raise IKSetupError(
            f"backend 'mink' cannot hold the CoM of {robot.name!r}: mink's ComTask uses the subtree "
            f"of MuJoCo body 1, and {why}; use backend 'qp', or put the robot first in the scene")
