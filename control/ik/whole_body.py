"""Whole-body differential IK for any robot: one task set (a frozen config), two backends.

The task set is named by a frozen :class:`WholeBodyIKConfig` (no robot's names are built in):

* held frames F_h (e.g. feet): pose held at the start pose, ``e = log6(X_FT)`` [m, rad];
* target frames F_t (e.g. palms): position targets p_WT [m] in the world (orientation weight 0;
  the target orientation is the start one, as in mink's ``FrameTask``);
* the base frame B (e.g. pelvis): orientation held, ``e = log3(R_BT)`` [rad];
* the centre of mass C (optional): world x and y, ``e = p_WC - p_target`` [m] (z free);
* posture: ``e = q (-) q_ref`` [rad], a regulariser (its residual does not gate convergence);

under joint position limits, optional per-joint speed limits and, for a floating base, base
speed limits. Two backends build that same set:

* ``"qp"`` (:class:`QPWholeBodyIK`, here): our Pinocchio QP (:class:`~mbctl.control.ik.diff_ik.DiffIK`)
  on the tasks of :mod:`mbctl.control.tasks`;
* ``"mink"`` (:class:`~mbctl.control.ik.mink_backend.MinkWholeBodyIK`): mink over
  ``robot.mj_model``; frames are MuJoCo sites or bodies.

:func:`~mbctl.control.ik.factory.make_whole_body_ik` picks one by name.

The two build the same QP step for step, up to round-off, with two deliberate differences: on a
ball joint our posture Jacobian is the exact ``pin.dDifference`` block while mink's is the
identity (the steps differ by O(cost^2 |e|^2)), and at rotation errors below about 1e-6 rad
mink's ``SE3.jlog`` drops the translation-rotation coupling of the pose Jacobian while
Pinocchio's ``Jlog6`` (ours) keeps it.

Public states (``q`` (nq,), ``v`` (nv,)) are in Pinocchio's convention for both backends.
Residuals are computed the same way for both (world positions, rotation angles from each
backend's own kinematics), so the two are comparable entry by entry; both run the one IK loop
(:func:`mbctl.control.ik.loop.iterate`) and return its :class:`~mbctl.control.ik.loop.IKResult`.
"""

from __future__ import annotations

import abc
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from mbctl.control.exceptions import IKSetupError
from mbctl.control.ik.diff_ik import DiffIK
from mbctl.control.ik.limits import (
    FloatingBaseVelocityLimit,
    JointPositionLimit,
    JointVelocityLimit,
    Limit,
)
from mbctl.control.ik.loop import IKResult, iterate
from mbctl.control.tasks.base import Task
from mbctl.control.tasks.com import ComTask
from mbctl.control.tasks.frame_orientation import FrameOrientationTask
from mbctl.control.tasks.frame_pose import FramePoseTask
from mbctl.control.tasks.posture import PostureTask
from mbctl.control.tasks.residuals import TaskResidual, Tolerance
from mbctl.control.tasks.state import KinematicState
from mbctl.exceptions import unknown_name_message
from mbctl.robots.model_pair import Robot


@dataclass(frozen=True)
class WholeBodyIKConfig:
    """The whole-body task set (frame names) with its weights and limits.

    Attributes:
        held_frames: Frames whose start pose is held (MuJoCo sites or bodies).
        target_frames: Frames that get world position targets (MuJoCo sites or bodies).
        base_frame: Frame whose start orientation is held, or None.
        com: Add a CoM task on world x and y.
        held_position_cost: [cost]/[m].
        held_orientation_cost: [cost]/[rad].
        target_position_cost: [cost]/[m] (target orientation is free).
        com_cost: [cost]/[m] on world x and y.
        base_orientation_cost: [cost]/[rad].
        posture_cost: [cost]/[rad].
        lm_damping: Levenberg-Marquardt scale [-] on held and target frames.
        damping: Global LM damping on all dofs [cost].
        joint_position_gain: Fraction in (0, 1] of the distance to a joint limit per step.
        joint_max_velocity: Per-joint speed bound [rad/s] (trust region ``v dt`` per step), or
            None for no per-joint speed bound.
        base_max_linear_velocity: Base linear speed bound per axis [m/s] (floating base only).
        base_max_angular_velocity: Base angular speed bound per axis [rad/s] (floating base only).
        dt: Step duration [s] the velocity bounds are scaled by.
    """

    held_frames: tuple[str, ...] = ()
    target_frames: tuple[str, ...] = ()
    base_frame: str | None = None
    com: bool = False
    held_position_cost: float = 10.0
    held_orientation_cost: float = 1.0
    target_position_cost: float = 5.0
    com_cost: float = 10.0
    base_orientation_cost: float = 10.0
    posture_cost: float = 1e-2
    lm_damping: float = 1.0
    damping: float = 1e-3
    joint_position_gain: float = 0.95
    joint_max_velocity: float | None = 2.0
    base_max_linear_velocity: float = 1.0
    base_max_angular_velocity: float = 2.0
    dt: float = 1.0

    def __post_init__(self) -> None:
        """Validate names and ranges."""
        object.__setattr__(self, "held_frames", tuple(self.held_frames))
        object.__setattr__(self, "target_frames", tuple(self.target_frames))
        frames = [*self.held_frames, *self.target_frames]
        if self.base_frame is not None:
            frames.append(self.base_frame)
        repeated = sorted({f for f in frames if frames.count(f) > 1})
        if repeated:
            raise IKSetupError(
                f"WholeBodyIKConfig: frames {repeated} appear more than once among held_frames, "
                "target_frames and base_frame; give each frame one role"
            )
        if not (self.held_frames or self.target_frames or self.com or self.base_frame):
            raise IKSetupError(
                "WholeBodyIKConfig has no task: give held_frames, target_frames, base_frame or com"
            )
        for name in ("held_position_cost", "held_orientation_cost", "target_position_cost",
                     "com_cost", "base_orientation_cost", "posture_cost", "lm_damping", "damping"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0.0):
                raise IKSetupError(f"WholeBodyIKConfig.{name} must be >= 0; got {value!r}")
        positive = ["base_max_linear_velocity", "base_max_angular_velocity", "dt"]
        if self.joint_max_velocity is not None:
            positive.append("joint_max_velocity")
        for name in positive:
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0.0):
                raise IKSetupError(f"WholeBodyIKConfig.{name} must be > 0; got {value!r}")
        if not 0.0 < self.joint_position_gain <= 1.0:
            raise IKSetupError(
                f"WholeBodyIKConfig.joint_position_gain must be in (0, 1]; "
                f"got {self.joint_position_gain!r}"
            )

    @property
    def frames(self) -> tuple[str, ...]:
        """Every frame the task set names (held, target, base)."""
        base = (self.base_frame,) if self.base_frame is not None else ()
        return (*self.held_frames, *self.target_frames, *base)


def mujoco_frame_type(robot: Robot, frame: str) -> str:
    """``"site"`` or ``"body"``: what MuJoCo object ``frame`` names (sites first).

    Raises:
        IKSetupError: Neither a site nor a body; the message lists the available names.
    """
    if frame in robot.sites:
        return "site"
    if frame in robot.bodies:
        return "body"
    raise IKSetupError(unknown_name_message("IK frame (a MuJoCo site or body)", frame,
                                            [*robot.sites, *robot.bodies]))


def hinge_names(robot: Robot) -> list[str]:
    """Names of the robot's 1-dof joints (hinge and slide), model order."""
    return [j.name for j in robot.joints.values() if j.kind in ("hinge", "slide")]


class WholeBodyIK(abc.ABC):
    """What both backends share: the checks, the targets, the residuals and the solve loop.

    Attributes:
        robot: The model pair.
        config: The task set, weights and limits.
        solver: qpsolvers backend name.
        position_limit: Joint position limit on the Pinocchio model (for margin reports).
    """

    backend: ClassVar[str]

    def __init__(
        self,
        robot: Robot,
        config: WholeBodyIKConfig,
        q_ref: npt.ArrayLike,
        solver: str = "daqp",
    ):
        """Build tasks and limits; every target starts at the pose ``q_ref`` (nq,), Pinocchio.

        Args:
            robot: The model pair.
            config: The task set (frames must be MuJoCo sites or bodies of ``robot``).
            q_ref: Configuration (nq,) whose poses are the first targets (posture reference too).
            solver: qpsolvers backend name.

        Raises:
            IKSetupError: A frame that is not a site or body of the robot, or an unavailable solver.
        """
        for frame in config.frames:
            mujoco_frame_type(robot, frame)
            if not robot.pin_model.existFrame(frame):
                raise IKSetupError(f"{frame!r} is a MuJoCo {mujoco_frame_type(robot, frame)} of "
                                   f"{robot.name!r} but not a Pinocchio frame; add it to both engines")
        self.robot = robot
        self.config = config
        self.solver = solver
        self.position_limit = JointPositionLimit(robot.pin_model, gain=config.joint_position_gain)
        self._targets: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        self._com_target = np.zeros(3)
        self._q_ref = np.array(q_ref, dtype=float)
        self._build()
        self.reset_targets(q_ref)

    # ------------------------------------------------------------------ backend hooks
    @abc.abstractmethod
    def _build(self) -> None:
        """Create the tasks and limits."""

    @abc.abstractmethod
    def update(self, q: npt.ArrayLike) -> None:
        """Move the kinematics to ``q`` (nq,), Pinocchio convention."""

    @property
    @abc.abstractmethod
    def q(self) -> np.ndarray:
        """Current configuration (nq,), Pinocchio convention (a copy)."""

    @abc.abstractmethod
    def frame_transform(self, frame: str) -> tuple[np.ndarray, np.ndarray]:
        """``(R_WF (3, 3), p_WF (3,) [m])`` of ``frame`` at the current configuration."""

    @abc.abstractmethod
    def com(self) -> np.ndarray:
        """Centre of mass p_WC (3,) [m] at the current configuration."""

    @abc.abstractmethod
    def _push_frame_target(self, frame: str, R_WT: np.ndarray, p_WT: np.ndarray) -> None:
        """Give the backend task of ``frame`` the target pose (R_WT, p_WT)."""

    @abc.abstractmethod
    def _push_com_target(self, p: np.ndarray) -> None:
        """Give the backend's CoM task the target (3,) [m]."""

    @abc.abstractmethod
    def _push_posture_target(self, q: np.ndarray) -> None:
        """Give the backend's posture task the reference ``q`` (nq,), Pinocchio convention."""

    @abc.abstractmethod
    def step(self, q: npt.ArrayLike) -> np.ndarray:
        """One step at ``q`` (nq,); returns the velocity ``v`` (nv,), Pinocchio convention."""

    @abc.abstractmethod
    def advance(self) -> float:
        """Solve one step at the current configuration, integrate it; its inf-norm [rad or m]."""

    # ------------------------------------------------------------------ targets
    def reset_targets(self, q: npt.ArrayLike) -> None:
        """Every target (frames, CoM, posture) at the pose ``q`` (nq,), Pinocchio convention."""
        qa = np.array(q, dtype=float)
        self.update(qa)
        for frame in self.config.frames:
            R, p = self.frame_transform(frame)
            self._targets[frame] = (R.copy(), p.copy())
            self._push_frame_target(frame, R, p)
        if self.config.com:
            self._com_target = self.com().copy()
            self._push_com_target(self._com_target)
        self._q_ref = qa
        self._push_posture_target(qa)

    def frame_position(self, frame: str) -> np.ndarray:
        """Current position p_WF (3,) [m] of ``frame`` (any MuJoCo site or body of the task set)."""
        return np.array(self.frame_transform(frame)[1])

    def set_target_position(self, frame: str, position: npt.ArrayLike) -> None:
        """World position target p_WT (3,) [m] of a target frame; orientation stays the start one.

        Raises:
            IKSetupError: ``frame`` is not one of ``config.target_frames``, or not a finite (3,).
        """
        if frame not in self.config.target_frames:
            raise IKSetupError(unknown_name_message("IK target frame", frame,
                                                    self.config.target_frames))
        p = np.array(position, dtype=float)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise IKSetupError(f"target of {frame!r} must be a finite (3,) position [m]; got {position!r}")
        R = self._targets[frame][0]
        self._targets[frame] = (R, p)
        self._push_frame_target(frame, R, p)

    def set_com_target(self, xy: npt.ArrayLike) -> None:
        """CoM target (x, y) [m] in the world (z is free).

        Raises:
            IKSetupError: The task set has no CoM task, or ``xy`` is not 2 finite numbers.
        """
        if not self.config.com:
            raise IKSetupError("this task set has no CoM task; build it with WholeBodyIKConfig(com=True)")
        xy_a = np.asarray(xy, dtype=float)
        if xy_a.shape != (2,) or not np.all(np.isfinite(xy_a)):
            raise IKSetupError(f"CoM target must be finite (x, y) [m]; got {xy!r}")
        self._com_target = self._com_target.copy()
        self._com_target[:2] = xy_a
        self._push_com_target(self._com_target)

    def target_positions(self) -> dict[str, np.ndarray]:
        """Position targets p_WT (3,) [m] of every held and target frame (copies)."""
        return {f: self._targets[f][1].copy() for f in (*self.config.held_frames,
                                                        *self.config.target_frames)}

    def target_rotations(self) -> dict[str, np.ndarray]:
        """Orientation targets R_WT (3, 3) of every held frame and the base frame (copies)."""
        base = (self.config.base_frame,) if self.config.base_frame is not None else ()
        return {f: self._targets[f][0].copy() for f in (*self.config.held_frames, *base)}

    @property
    def com_target(self) -> np.ndarray | None:
        """CoM target (3,) [m] (z unused), or None without a CoM task."""
        return self._com_target.copy() if self.config.com else None

    # ------------------------------------------------------------------ residuals and solve
    def task_residuals(self) -> dict[str, TaskResidual]:
        """Every task's residual at the current configuration (computed alike for both backends)."""
        out: dict[str, TaskResidual] = {}
        cfg = self.config
        for frame in cfg.frames:
            R, p = self.frame_transform(frame)
            R_T, p_T = self._targets[frame]
            position = None if frame == cfg.base_frame else float(np.linalg.norm(p - p_T))
            angle = None
            if frame in cfg.held_frames or frame == cfg.base_frame:
                angle = float(np.linalg.norm(pin.log3(R_T.T @ R)))
            out[frame] = TaskResidual(position_m=position, orientation_rad=angle)
        if cfg.com:
            out["com"] = TaskResidual(position_m=float(np.linalg.norm(self.com()[:2] - self._com_target[:2])))
        deviation = pin.difference(self.robot.pin_model, self._q_ref, self.q)
        out["posture"] = TaskResidual(deviation=float(np.linalg.norm(deviation)))
        return out

    @property
    def levels(self) -> tuple[tuple[str, ...], ...]:
        """Task names (as in :meth:`task_residuals`) by priority level, level 0 first."""
        names = [*self.config.frames, *(("com",) if self.config.com else ()), "posture"]
        return (tuple(names),)

    def solve(
        self,
        q0: npt.ArrayLike,
        tolerance: Tolerance | None = None,
        max_iters: int = 50,
        step_tol: float = 1e-6,
    ) -> IKResult:
        """Iterate from ``q0`` (nq,) until every task meets ``tolerance`` (the one IK loop).

        An unreachable target is not an error: iteration stops when the step becomes negligible
        (``stalled``) and the residuals say how far each task is from its target.

        Args:
            q0: Initial configuration (nq,), Pinocchio convention.
            tolerance: Position [m] and orientation [rad] tolerances (default 1 mm, 0.01 rad).
            max_iters: Maximum number of steps.
            step_tol: Stop when the step's inf-norm falls below this [rad or m].

        Raises:
            IKSetupError: A negative ``step_tol`` or ``max_iters`` < 1.
            IKInfeasible: A step's QP has no solution (qp backend).
        """
        return iterate(self, q0, tolerance or Tolerance(), max_iters, step_tol)


class QPWholeBodyIK(WholeBodyIK):
    """The task set on our Pinocchio QP (``DiffIK``); limits and buffers built once.

    Attributes:
        tasks: Our tasks by role: each held/target frame, the base frame, "com", "posture".
        ik: The underlying ``DiffIK``.
    """

    backend = "qp"

    def _build(self) -> None:
        cfg, m = self.config, self.robot.pin_model
        self.tasks: dict[str, Task] = {}
        for frame in cfg.held_frames:
            self.tasks[frame] = FramePoseTask(frame, m, cfg.held_position_cost, cfg.held_orientation_cost,
                                              lm_damping=cfg.lm_damping, name=frame)
        for frame in cfg.target_frames:
            self.tasks[frame] = FramePoseTask(frame, m, cfg.target_position_cost, 0.0,
                                              lm_damping=cfg.lm_damping, name=frame)
        if cfg.base_frame is not None:
            self.tasks[cfg.base_frame] = FrameOrientationTask(cfg.base_frame, m, cfg.base_orientation_cost,
                                                              name=cfg.base_frame)
        if cfg.com:
            self.tasks["com"] = ComTask([cfg.com_cost, cfg.com_cost, 0.0], name="com")
        self.tasks["posture"] = PostureTask(m, cfg.posture_cost, name="posture")
        limits: list[Limit] = [self.position_limit]
        if cfg.joint_max_velocity is not None:
            speeds = {n: cfg.joint_max_velocity for n in hinge_names(self.robot)}
            limits.append(JointVelocityLimit(m, speeds))
        if self.robot.has_floating_base:
            limits.append(FloatingBaseVelocityLimit(m, cfg.base_max_linear_velocity,
                                                    cfg.base_max_angular_velocity))
        self.ik = DiffIK(m, list(self.tasks.values()), limits, self.solver, cfg.damping)

    @property
    def state(self) -> KinematicState:
        """Kinematic state at the last update."""
        return self.ik.state

    def update(self, q: npt.ArrayLike) -> None:
        """Move the kinematics to ``q`` (nq,), Pinocchio convention."""
        self.ik.update(q)

    @property
    def q(self) -> np.ndarray:
        """Current configuration (nq,), Pinocchio convention (a copy)."""
        return np.array(self.ik.state.q)

    def frame_pose(self, frame: str) -> pin.SE3:
        """Current pose X_WF of ``frame`` (a copy)."""
        return pin.SE3(self.ik.state.frame_pose(self.ik.state.frame_id(frame)))

    def frame_transform(self, frame: str) -> tuple[np.ndarray, np.ndarray]:
        """``(R_WF (3, 3), p_WF (3,) [m])`` at the current configuration."""
        X = self.ik.state.frame_pose(self.ik.state.frame_id(frame))
        return X.rotation, X.translation

    def com(self) -> np.ndarray:
        """Centre of mass p_WC (3,) [m]."""
        return np.array(self.ik.state.com())

    def _push_frame_target(self, frame: str, R_WT: np.ndarray, p_WT: np.ndarray) -> None:
        task = self.tasks[frame]
        if isinstance(task, (FramePoseTask, FrameOrientationTask)):
            task.set_target(pin.SE3(R_WT, p_WT))

    def _push_com_target(self, p: np.ndarray) -> None:
        task = self.tasks["com"]
        if isinstance(task, ComTask):
            task.set_target(p)

    def _push_posture_target(self, q: np.ndarray) -> None:
        task = self.tasks["posture"]
        if isinstance(task, PostureTask):
            task.set_target(q)

    def step(self, q: npt.ArrayLike) -> np.ndarray:
        """One step at ``q`` (nq,); ``v`` (nv,) in Pinocchio's convention."""
        return self.ik.step(q, self.config.dt).v

    def advance(self) -> float:
        """Solve one step at the current configuration, integrate it; its inf-norm [rad or m]."""
        out = self.ik.solve_step(self.config.dt)
        self.ik.update(pin.integrate(self.robot.pin_model, self.ik.state.q, out.dq))
        return float(np.max(np.abs(out.dq)))


def joint_positions_by_name(robot: Robot, q: npt.ArrayLike) -> dict[str, list[float]]:
    """``q`` (nq,) split by joint name (free joint: x, y, z, qx, qy, qz, qw)."""
    qa = np.asarray(q, dtype=float)
    return {j.name: qa[j.idx_q : j.idx_q + j.nq].tolist() for j in robot.joints.values()}
