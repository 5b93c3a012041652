"""MuJoCo's own kinematics at a given configuration: where the plant puts bodies, sites and geoms.

A :class:`PlantKinematics` owns a scratch ``MjData`` of a model (never the simulator's, so a
running plant is untouched) and runs ``mj_kinematics`` only: no dynamics, never a step. It is the
plant's word on a pose, against which an analytic answer (Pinocchio's, an IK's) is checked, and
what a replay needs to place markers. ``collide`` adds MuJoCo's collision detection at the same
pose (the contacts within each geom's margin).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import mujoco
import numpy.typing as npt

from mbctl.robots.exceptions import RobotError

if TYPE_CHECKING:  # the model pair's load-time check uses this module
    from mbctl.robots.model_pair import Robot


class PlantKinematics:
    """MuJoCo's kinematics of ``model`` on data of its own.

    Args:
        model: The MuJoCo model (read, never stepped); default ``robot.mj_model``. A copy with
            edits (e.g. wider geom margins) may be given.
        robot: The model pair whose configurations :meth:`at` takes (Pinocchio convention);
            without one, only :meth:`at_qpos`.

    Attributes:
        model: The model.
        data: The scratch data: after :meth:`at` or :meth:`at_qpos`, its ``xpos``, ``xmat``,
            ``xipos``, ``site_xpos``, ``site_xmat``, ``geom_xpos`` and ``geom_xmat`` hold the pose.
    """

    def __init__(self, model: mujoco.MjModel | None = None, robot: Robot | None = None):
        if model is None:
            if robot is None:
                raise RobotError("PlantKinematics needs a model or a robot")
            model = robot.mj_model
        self.model = model
        self.robot = robot
        self.data = mujoco.MjData(model)

    def at_qpos(self, qpos: npt.ArrayLike) -> mujoco.MjData:
        """The data with the plant at ``qpos`` (nq of the model, MuJoCo's convention), kinematics run."""
        self.data.qpos[:] = qpos
        mujoco.mj_kinematics(self.model, self.data)
        return self.data

    def at(self, q: npt.ArrayLike) -> mujoco.MjData:
        """The data with the robot at ``q`` (nq,), Pinocchio convention (the scene's coordinates kept).

        Raises:
            RobotError: No robot was given.
        """
        if self.robot is None:
            raise RobotError("PlantKinematics.at takes a robot configuration: give the robot")
        self.robot.plant_qpos(q, self.data.qpos)
        mujoco.mj_kinematics(self.model, self.data)
        return self.data

    def collide(self) -> mujoco.MjData:
        """MuJoCo's collision detection at the current pose: ``data.contact[:data.ncon]``.

        Contacts within each geom's margin are listed (``contact.dist`` > 0 for those not
        touching), with the model's contype/conaffinity, parent-child and exclude filters.
        """
        mujoco.mj_collision(self.model, self.data)
        return self.data
