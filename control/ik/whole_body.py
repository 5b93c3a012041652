"""Whole-body IK on the Unitree G1: feet held, palm targets, CoM, pelvis orientation, posture.

The same task set is built twice, once on our Pinocchio QP (``PinocchioWholeBodyIK``) and once
on mink over the MuJoCo model (``MinkWholeBodyIK``); given the same state and targets both give
the same velocity step (``tests/test_g1_ik.py`` checks it). Public states are in Pinocchio's
convention; the mink wrapper converts with the model pair's ``StateConverter`` (MuJoCo's
free-joint linear velocity is in the world frame, Pinocchio's in the base frame).

Palm sites. The Menagerie G1 has no palm sites, so ``with_palm_sites`` adds them at load time
(recorded in ``robot.source.edits``):

* MuJoCo (MjSpec): site ``left_palm`` on body ``left_wrist_yaw_link`` and ``right_palm`` on
  ``right_wrist_yaw_link``, at ``PALM_OFFSET_IN_WRIST_YAW_M`` = (0.08, 0, 0) m in the body frame,
  identity orientation. The rubber hand mesh starts at x = 0.0415 m on that link and the link's
  CoM (hand included) is at x = 0.0708 m, so 0.08 m is about mid-palm along the hand's long axis.
* Pinocchio: ``pin.Model.addFrame`` of an ``OP_FRAME`` with the same name on the wrist-yaw joint,
  placed at (body frame placement) * (offset).
"""

from __future__ import annotations

import abc
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, cast

import mujoco
import numpy as np
import numpy.typing as npt
import pinocchio as pin

from mbctl.control.exceptions import IKSetupError
from mbctl.control.ik.limits import (
    FloatingBaseVelocityLimit,
    JointPositionLimit,
    JointVelocityLimit,
)
from mbctl.control.ik.solve import DiffIK, IKResult, IKStep
from mbctl.control.ik.tasks import (
    ComTask,
    FrameOrientationTask,
    FramePoseTask,
    PostureTask,
    Task,
)
from mbctl.robots.model_pair import Robot

#: Palm site offset [m] in each wrist-yaw link frame (see the module docstring for the choice).
PALM_OFFSET_IN_WRIST_YAW_M = (0.08, 0.0, 0.0)

#: Palm site name -> the body it is attached to.
PALM_SITES = {"left_palm": "left_wrist_yaw_link", "right_palm": "right_wrist_yaw_link"}

FEET = ("left_foot", "right_foot")
PELVIS = "pelvis"


def with_palm_sites(robot: Robot) -> Robot:
    """A copy of the G1 model pair with ``left_palm``/``right_palm`` sites (both engines).

    Raises:
        IKSetupError: The robot lacks the wrist-yaw bodies (not a G1).
    """
    missing = [b for b in PALM_SITES.values() if b not in robot.bodies]
    if missing:
        raise IKSetupError(
            f"{robot.name!r} has no bodies {missing}; palm sites are defined for the Unitree G1."
        )
    if all(s in robot.sites for s in PALM_SITES):
        return robot
    offset = np.array(PALM_OFFSET_IN_WRIST_YAW_M)

    def mj_edit(spec: mujoco.MjSpec) -> None:
        for site, body in PALM_SITES.items():
            spec.body(body).add_site(name=site, pos=offset, size=[0.01, 0.01, 0.01])

    def pin_edit(model: pin.Model) -> pin.Model:
        for site, body in PALM_SITES.items():
            body_frame = model.frames[model.getFrameId(body, pin.FrameType.BODY)]
            placement = body_frame.placement * pin.SE3(np.eye(3), offset)
            model.addFrame(
                pin.Frame(
                    site,
                    body_frame.parentJoint,
                    model.getFrameId(body, pin.FrameType.BODY),
                    placement,
                    pin.FrameType.OP_FRAME,
                )
            )
        return model

    return robot.with_edits(
        f"sites left_palm/right_palm at {PALM_OFFSET_IN_WRIST_YAW_M} m in the wrist-yaw links "
        "(MjSpec add_site; Pinocchio OP_FRAME)",
        mj_edit,
        pin_edit,
    )


@dataclass(frozen=True)
class WholeBodyIKConfig:
    """Task weights and limits of the G1 whole-body IK (mink's humanoid example, plus limits).

    Attributes:
        foot_position_cost: [cost]/[m].
        foot_orientation_cost: [cost]/[rad].
        palm_position_cost: [cost]/[m] (palm orientation is free).
        com_cost: [cost]/[m] on world x and y (z is free).
        pelvis_orientation_cost: [cost]/[rad].
        posture_cost: [cost]/[rad].
        lm_damping: Levenberg-Marquardt scale [-] on feet and palms (keeps unreachable targets
            tame; mink's example uses 1).
        damping: Global LM damping on all dofs [cost].
        joint_position_gain: Fraction in (0, 1] of the distance to a joint limit per step.
        joint_max_velocity: Per-joint speed bound [rad/s] (trust region: ``v dt`` per step).
        base_max_linear_velocity: Base linear speed bound per axis, base frame [m/s].
        base_max_angular_velocity: Base angular speed bound per axis, base frame [rad/s].
        dt: Step duration [s] the velocity bounds are scaled by.
    """

    foot_position_cost: float = 10.0
    foot_orientation_cost: float = 1.0
    palm_position_cost: float = 5.0
    com_cost: float = 10.0
    pelvis_orientation_cost: float = 10.0
    posture_cost: float = 1e-2
    lm_damping: float = 1.0
    damping: float = 1e-3
    joint_position_gain: float = 0.95
    joint_max_velocity: float = 2.0
    base_max_linear_velocity: float = 1.0
    base_max_angular_velocity: float = 2.0
    dt: float = 1.0

    def __post_init__(self) -> None:
        """Validate ranges."""
        for name in (
            "foot_position_cost",
            "foot_orientation_cost",
            "palm_position_cost",
            "com_cost",
            "pelvis_orientation_cost",
            "posture_cost",
            "lm_damping",
            "damping",
        ):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0.0):
                raise IKSetupError(f"WholeBodyIKConfig.{name} must be >= 0; got {value!r}")
        for name in (
            "joint_max_velocity",
            "base_max_linear_velocity",
            "base_max_angular_velocity",
            "dt",
        ):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0.0):
                raise IKSetupError(f"WholeBodyIKConfig.{name} must be > 0; got {value!r}")
        if not 0.0 < self.joint_position_gain <= 1.0:
            raise IKSetupError(
                f"WholeBodyIKConfig.joint_position_gain must be in (0, 1]; "
                f"got {self.joint_position_gain!r}"
            )


def _hinge_names(robot: Robot) -> list[str]:
    return [j.name for j in robot.joints.values() if j.kind in ("hinge", "slide")]


class _WholeBodyIK(abc.ABC):
    """What both G1 whole-body IK wrappers share: checks, config, and the build-then-target order.

    Subclasses implement ``_build`` (tasks and limits) and ``reset_targets``.
    """

    def __init__(
        self,
        robot: Robot,
        q_ref: npt.ArrayLike,
        config: WholeBodyIKConfig | None = None,
        solver: str = "daqp",
    ):
        """Build tasks and limits; targets start at the pose ``q_ref`` (nq,), Pinocchio convention.

        Args:
            robot: The G1 model pair with palm sites (``with_palm_sites``).
            q_ref: Configuration (nq,) whose poses are the first targets.
            config: Weights and limits (default ``WholeBodyIKConfig()``).
            solver: qpsolvers backend name.

        Raises:
            IKSetupError: The robot lacks palm sites (use ``with_palm_sites``).
        """
        _require_palms(robot)
        self.robot = robot
        self.config = config or WholeBodyIKConfig()
        self.solver = solver
        self._build(self.config)
        self.reset_targets(q_ref)

    @abc.abstractmethod
    def _build(self, cfg: WholeBodyIKConfig) -> None:
        """Create the tasks and limits."""

    @abc.abstractmethod
    def reset_targets(self, q: npt.ArrayLike) -> None:
        """Every target at the pose ``q`` (nq,), Pinocchio convention."""


def _check_palm(palm: str) -> None:
    if palm not in PALM_SITES:
        raise IKSetupError(f"Unknown palm {palm!r}; available: {', '.join(PALM_SITES)}.")


class PinocchioWholeBodyIK(_WholeBodyIK):
    """The G1 task set on our Pinocchio QP (``DiffIK``); limits and buffers built once.

    Attributes:
        robot: The model pair (with palm sites).
        config: Weights and limits.
        tasks: Tasks by role: "left_foot", "right_foot", "left_palm", "right_palm", "com",
            "pelvis", "posture".
        position_limit: The joint position limit (for margin reports).
        ik: The underlying ``DiffIK``.
    """

    def _build(self, cfg: WholeBodyIKConfig) -> None:
        m = self.robot.pin_model
        self.tasks: dict[str, Task] = {
            foot: FramePoseTask(
                foot, m, cfg.foot_position_cost, cfg.foot_orientation_cost,
                lm_damping=cfg.lm_damping, name=foot,
            )
            for foot in FEET
        }
        for palm in PALM_SITES:
            self.tasks[palm] = FramePoseTask(
                palm, m, cfg.palm_position_cost, 0.0, lm_damping=cfg.lm_damping, name=palm
            )
        self.tasks["com"] = ComTask([cfg.com_cost, cfg.com_cost, 0.0], name="com")
        self.tasks["pelvis"] = FrameOrientationTask(
            PELVIS, m, cfg.pelvis_orientation_cost, name="pelvis"
        )
        self.tasks["posture"] = PostureTask(m, cfg.posture_cost, name="posture")
        self.position_limit = JointPositionLimit(m, gain=cfg.joint_position_gain)
        limits = [
            self.position_limit,
            JointVelocityLimit(m, {n: cfg.joint_max_velocity for n in _hinge_names(self.robot)}),
            FloatingBaseVelocityLimit(
                m, cfg.base_max_linear_velocity, cfg.base_max_angular_velocity
            ),
        ]
        self.ik = DiffIK(m, list(self.tasks.values()), limits, self.solver, cfg.damping)

    @property
    def state(self):
        """Kinematic state (``IKState``) at the last update."""
        return self.ik.state

    def reset_targets(self, q: npt.ArrayLike) -> None:
        """Set every target to the pose at ``q`` (nq,) (feet, palms, CoM, pelvis, posture)."""
        self.ik.update(q)
        for task in self.tasks.values():
            task.set_target_from_state(self.ik.state)

    def frame_pose(self, name: str) -> pin.SE3:
        """Current pose of a frame (after the last update)."""
        return self.ik.state.frame_pose(self.ik.state.frame_id(name))

    def set_palm_target(self, palm: str, position: npt.ArrayLike) -> None:
        """Target position [m] (world) of ``palm``; the target orientation is the current one.

        Raises:
            IKSetupError: Not a palm site name.
        """
        _check_palm(palm)
        X = pin.SE3(self.frame_pose(palm))
        X.translation = np.asarray(position, dtype=float)
        cast(FramePoseTask, self.tasks[palm]).set_target(X)

    def set_com_target(self, xy: npt.ArrayLike) -> None:
        """CoM target (x, y) [m] in the world (z is free)."""
        p = np.array(self.ik.state.com())
        p[:2] = np.asarray(xy, dtype=float)
        cast(ComTask, self.tasks["com"]).set_target(p)

    def step(self, q: npt.ArrayLike) -> IKStep:
        """One step at ``q`` (nq,); ``v`` (nv,) in Pinocchio's convention."""
        return self.ik.step(q, self.config.dt)

    def solve(self, q0: npt.ArrayLike, tol: float = 1e-3, max_iters: int = 50) -> IKResult:
        """Iterate to convergence (position tolerance ``tol`` [m])."""
        return self.ik.solve(q0, self.config.dt, tol=tol, tol_rad=10 * tol, max_iters=max_iters)


class MinkWholeBodyIK(_WholeBodyIK):
    """The same task set on mink (MuJoCo model); limits built once.

    Attributes:
        robot: The model pair (with palm sites).
        config: Weights and limits.
        configuration: ``mink.Configuration`` on ``robot.mj_model``.
        tasks: mink tasks by role (as in ``PinocchioWholeBodyIK``).
        limits: mink limits (configuration, joint velocity, free-joint velocity).
    """

    def _build(self, cfg: WholeBodyIKConfig) -> None:
        import mink

        self._mink = mink
        m = self.robot.mj_model
        self.configuration = mink.Configuration(m)
        self.tasks: dict[str, Any] = {  # mink task types differ in their target setters
            foot: mink.FrameTask(
                foot, "site", cfg.foot_position_cost, cfg.foot_orientation_cost,
                lm_damping=cfg.lm_damping,
            )
            for foot in FEET
        }
        for palm in PALM_SITES:
            self.tasks[palm] = mink.FrameTask(
                palm, "site", cfg.palm_position_cost, 0.0, lm_damping=cfg.lm_damping
            )
        self.tasks["com"] = mink.ComTask(cost=[cfg.com_cost, cfg.com_cost, 0.0])
        self.tasks["pelvis"] = mink.FrameTask(PELVIS, "body", 0.0, cfg.pelvis_orientation_cost)
        self.tasks["posture"] = mink.PostureTask(m, cost=cfg.posture_cost)
        self._task_list = list(self.tasks.values())
        self.limits = [
            mink.ConfigurationLimit(m, gain=cfg.joint_position_gain),
            mink.VelocityLimit(m, {n: cfg.joint_max_velocity for n in _hinge_names(self.robot)}),
            mink.FreeJointVelocityLimit(
                m, cfg.base_max_linear_velocity, cfg.base_max_angular_velocity
            ),
        ]

    def update(self, q: npt.ArrayLike) -> None:
        """Set the configuration from ``q`` (nq,), Pinocchio convention."""
        self.configuration.update(self.robot.converter.q_pin_to_mj(q))

    def reset_targets(self, q: npt.ArrayLike) -> None:
        """Every target at the pose ``q`` (nq,), Pinocchio convention."""
        self.update(q)
        for name, task in self.tasks.items():
            if name == "com":
                task.set_target(self.configuration.data.subtree_com[1].copy())
            else:
                task.set_target_from_configuration(self.configuration)

    def set_palm_target(self, palm: str, position: npt.ArrayLike) -> None:
        """Target position [m] (world) of ``palm``; orientation kept at the current one."""
        _check_palm(palm)
        X = self.configuration.get_transform_frame_to_world(palm, "site")
        target = self._mink.SE3.from_rotation_and_translation(
            X.rotation(), np.asarray(position, dtype=float)
        )
        self.tasks[palm].set_target(target)

    def set_com_target(self, xy: npt.ArrayLike) -> None:
        """CoM target (x, y) [m] in the world (z is free)."""
        p = self.configuration.data.subtree_com[1].copy()
        p[:2] = np.asarray(xy, dtype=float)
        cast(ComTask, self.tasks["com"]).set_target(p)

    def step_mj(self) -> np.ndarray:
        """One step at the current configuration: MuJoCo qvel-convention velocity (nv,)."""
        return self._mink.solve_ik(
            self.configuration,
            self._task_list,
            self.config.dt,
            self.solver,
            damping=self.config.damping,
            limits=self.limits,
        )

    def step(self, q: npt.ArrayLike) -> np.ndarray:
        """One step at ``q`` (nq,, Pinocchio); returns ``v`` (nv,) in Pinocchio's convention."""
        self.update(q)
        return self.robot.converter.v_mj_to_pin(q, self.step_mj())

    def solve(
        self, q0: npt.ArrayLike, tol: float = 1e-3, max_iters: int = 50
    ) -> tuple[np.ndarray, int, dict[str, float]]:
        """Iterate mink (MuJoCo integration) until the palm and feet positions are within ``tol``.

        Returns:
            Final q (nq,) in Pinocchio's convention, iterations, palm/feet position errors [m].
        """
        self.update(q0)
        it = 0
        while True:
            errors = {
                n: float(np.linalg.norm(self.tasks[n].compute_error(self.configuration)[:3]))
                for n in (*FEET, *PALM_SITES)
            }
            if max(errors.values()) <= tol or it >= max_iters:
                break
            self.configuration.integrate_inplace(self.step_mj(), self.config.dt)
            it += 1
        return self.robot.converter.q_mj_to_pin(self.configuration.q), it, errors


def _require_palms(robot: Robot) -> None:
    missing = [s for s in PALM_SITES if s not in robot.sites]
    if missing:
        raise IKSetupError(
            f"{robot.name!r} has no sites {missing}; load it through with_palm_sites(robot)."
        )


def joint_positions_by_name(robot: Robot, q: npt.ArrayLike) -> Mapping[str, list[float]]:
    """``q`` (nq,) split by joint name (free joint: x, y, z, qx, qy, qz, qw)."""
    qa = np.asarray(q, dtype=float)
    return {
        j.name: qa[j.idx_q : j.idx_q + j.nq].tolist() for j in robot.joints.values()
    }
