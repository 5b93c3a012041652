"""Whole-body differential IK for any robot: one task set (a frozen config), two backends.

The task set is named by a frozen :class:`~mbctl.control.ik.config.WholeBodyIKConfig` (no
robot's names are built in):

* held frames F_h (e.g. feet): pose held at the start pose, ``e = log6(X_FT)`` [m, rad];
* target frames F_t (e.g. palms): position targets p_WT [m] in the world, or full poses (the
  ``oriented_frames``), or poses relative to another, possibly moving, frame
  (``relative_targets``); a frame's orientation target is its start one until set;
* the base frame B (e.g. pelvis): orientation held, ``e = log3(R_BT)`` [rad];
* the centre of mass C (optional): world x and y (and z with ``com_height``), ``e = p_WC - p_target``;
* posture: ``e = q (-) q_ref`` [rad], and optionally damping: regularisers (their residuals do not
  gate convergence);

under joint position limits, per-joint speed limits, base speed limits for a floating base and,
when the config names collision pairs, collision avoidance (a velocity damper on each pair's
MuJoCo distance). Tasks may be given priority levels (a lexicographic solve, see
:mod:`mbctl.control.ik.diff_ik`; our backend only). Two backends build that same set:

* ``"qp"`` (:class:`QPWholeBodyIK`, here): our Pinocchio QP (:class:`~mbctl.control.ik.diff_ik.DiffIK`)
  on the tasks of :mod:`mbctl.control.tasks`, collisions by
  :class:`~mbctl.control.ik.collision.CollisionAvoidanceLimit`;
* ``"mink"`` (:class:`~mbctl.control.ik.mink_backend.MinkWholeBodyIK`): mink over
  ``robot.mj_model``; frames are MuJoCo sites or bodies; mink's ``CollisionAvoidanceLimit`` on the
  same geom pairs.

:func:`~mbctl.control.ik.factory.make_whole_body_ik` picks one by name.

The two build the same QP, up to round-off, with three deliberate differences: on a ball joint
our posture Jacobian is the exact ``pin.dDifference`` block while mink's is the identity (the
steps differ by O(cost^2 |e|^2)); at rotation errors below 1e-5 rad (mink tests ``theta^2 <
1e-10``) mink's ``SE3.jlog`` drops the translation-rotation coupling of the pose Jacobian while
Pinocchio's ``Jlog6`` (ours) keeps it, so from a start at exactly the target orientation (the
first step of a position-only hand target) the steps differ; and mink divides the collision
bound by ``dt`` (the same at the default ``dt = 1 s``).

Public states (``q`` (nq,), ``v`` (nv,)) are in Pinocchio's convention for both backends.
Residuals are computed the same way for both (from each backend's own kinematics), so the two
are comparable entry by entry; both run the one IK loop (:func:`mbctl.control.ik.loop.iterate`)
and return its :class:`~mbctl.control.ik.loop.IKResult`.
"""

from __future__ import annotations

import abc
from typing import ClassVar, NamedTuple

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from mbctl.control.exceptions import IKSetupError
from mbctl.control.ik.collision import CollisionAvoidanceLimit
from mbctl.control.ik.config import WholeBodyIKConfig
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
from mbctl.control.tasks.damping import DampingTask
from mbctl.control.tasks.frame_orientation import FrameOrientationTask
from mbctl.control.tasks.frame_pose import FramePoseTask
from mbctl.control.tasks.posture import PostureTask
from mbctl.control.tasks.relative_frame import RelativeFrameTask
from mbctl.control.tasks.residuals import TaskResidual, Tolerance
from mbctl.control.tasks.state import KinematicState
from mbctl.exceptions import unknown_name_message
from mbctl.robots.collision import GeomPairs, resolve_pairs
from mbctl.robots.exceptions import RobotError
from mbctl.robots.model_pair import Robot

__all__ = ["FrameTarget", "QPWholeBodyIK", "WholeBodyIK", "WholeBodyIKConfig", "hinge_names",
           "joint_positions_by_name", "joint_speeds", "mujoco_frame_type"]


class FrameTarget(NamedTuple):
    """One frame's target, in the world or in its reference frame.

    Attributes:
        rotation: R_XT (3, 3), X the world or the reference frame.
        position: p_XT (3,) [m].
        reference: The reference frame's name, or None for the world.
        has_position: The position is a target (not for the base frame).
        has_orientation: The orientation is a target (held, base and oriented frames).
    """

    rotation: np.ndarray
    position: np.ndarray
    reference: str | None
    has_position: bool
    has_orientation: bool


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


def joint_speeds(robot: Robot, config: WholeBodyIKConfig) -> dict[str, float]:
    """Per-joint speed bounds [rad/s or m/s]: ``joint_max_velocity`` with the named overrides.

    Raises:
        IKSetupError: An override names a joint that is not a 1-dof joint of the robot.
    """
    hinges = hinge_names(robot)
    speeds = {n: config.joint_max_velocity for n in hinges} if config.joint_max_velocity is not None else {}
    for joint, speed in config.joint_max_velocities:
        if joint not in hinges:
            raise IKSetupError(unknown_name_message("1-dof joint (for a velocity limit)", joint, hinges))
        speeds[joint] = speed
    return speeds


class WholeBodyIK(abc.ABC):
    """What both backends share: the checks, the targets, the residuals and the solve loop.

    Attributes:
        robot: The model pair.
        config: The task set, weights and limits.
        solver: qpsolvers backend name.
        position_limit: Joint position limit on the Pinocchio model (for margin reports).
        collision_pairs: The geom pairs kept apart (None without collision avoidance).
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
            IKSetupError: A frame that is not a site or body of the robot, an unknown joint or
                collision name, or an unavailable solver.
        """
        for frame in (*config.frames, *config.reference_of.values()):
            mujoco_frame_type(robot, frame)
            if not robot.pin_model.existFrame(frame):
                raise IKSetupError(f"{frame!r} is a MuJoCo {mujoco_frame_type(robot, frame)} of "
                                   f"{robot.name!r} but not a Pinocchio frame; add it to both engines")
        self.robot = robot
        self.config = config
        self.solver = solver
        self.position_limit = JointPositionLimit(robot.pin_model, gain=config.joint_position_gain)
        self.collision_pairs: GeomPairs | None = None
        if config.collision_pairs:
            try:
                self.collision_pairs = resolve_pairs(robot, config.collision_pairs)
            except RobotError as exc:  # an unknown name, or a pair that leaves no geom pair
                raise IKSetupError(str(exc)) from None
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
        """Centre of mass p_WC (3,) [m] of the robot at the current configuration."""

    @abc.abstractmethod
    def _push_frame_target(self, frame: str, R_XT: np.ndarray, p_XT: np.ndarray) -> None:
        """Give the backend task of ``frame`` its target pose, in the world or its reference frame."""

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
    def target_frame_transform(self, frame: str) -> tuple[np.ndarray, np.ndarray]:
        """``(R_XF, p_XF)`` of ``frame`` in the frame its target is given in (world or reference)."""
        R_WF, p_WF = self.frame_transform(frame)
        reference = self.config.reference_of.get(frame)
        if reference is None:
            return R_WF, p_WF
        R_WR, p_WR = self.frame_transform(reference)
        return R_WR.T @ R_WF, R_WR.T @ (p_WF - p_WR)

    def reset_targets(self, q: npt.ArrayLike) -> None:
        """Every target (frames, CoM, posture) at the pose ``q`` (nq,), Pinocchio convention."""
        qa = np.array(q, dtype=float)
        self.update(qa)
        for frame in self.config.frames:
            R, p = self.target_frame_transform(frame)
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
        """Position target (3,) [m] of a target frame (in its reference frame for a relative target).

        The orientation target is kept (the start orientation until set).

        Raises:
            IKSetupError: ``frame`` is not one of ``config.target_frames``, or not a finite (3,).
        """
        self.set_target_pose(frame, position)

    def set_target_pose(self, frame: str, position: npt.ArrayLike,
                        rotation: npt.ArrayLike | None = None) -> None:
        """Pose target of a target frame: position (3,) [m] and rotation matrix (3, 3) (None: kept).

        Both are in the world, or in the reference frame for a relative target. The rotation is
        a target only for ``config.oriented_frames`` and relative targets with orientation cost.

        Raises:
            IKSetupError: ``frame`` is not a target frame; a position that is not a finite (3,);
                a rotation that is not a rotation matrix.
        """
        if frame not in self.config.target_frames:
            raise IKSetupError(unknown_name_message("IK target frame", frame,
                                                    self.config.target_frames))
        p = np.array(position, dtype=float)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise IKSetupError(f"target of {frame!r} must be a finite (3,) position [m]; got {position!r}")
        R = self._targets[frame][0]
        if rotation is not None:
            R = np.array(rotation, dtype=float)
            if (R.shape != (3, 3) or not np.all(np.isfinite(R))
                    or not np.allclose(R.T @ R, np.eye(3), atol=1e-9) or np.linalg.det(R) <= 0.0):
                raise IKSetupError(f"orientation target of {frame!r} must be a rotation matrix; "
                                   f"got {rotation!r}")
        self._targets[frame] = (R, p)
        self._push_frame_target(frame, R, p)

    def set_com_target(self, target: npt.ArrayLike) -> None:
        """CoM target (x, y) [m] in the world, or (x, y, z) with a CoM height task.

        Raises:
            IKSetupError: No CoM task; not 2 (or, with ``com_height``, 3) finite numbers.
        """
        if not self.config.com:
            raise IKSetupError("this task set has no CoM task; build it with WholeBodyIKConfig(com=True)")
        t = np.asarray(target, dtype=float)
        sizes = (2, 3) if self.config.com_height else (2,)
        if t.ndim != 1 or t.shape[0] not in sizes or not np.all(np.isfinite(t)):
            what = ("(x, y) or (x, y, z)" if self.config.com_height else
                    "(x, y) (the height is free; build the task set with com_height=True to hold it)")
            raise IKSetupError(f"CoM target must be finite {what} [m]; got {target!r}")
        self._com_target = self._com_target.copy()
        self._com_target[:t.shape[0]] = t
        self._push_com_target(self._com_target)

    def targets(self) -> dict[str, FrameTarget]:
        """Every frame's target (held, target and base frames), with what of it is a target (copies)."""
        cfg = self.config
        out = {}
        for frame in cfg.frames:
            R, p = self._targets[frame]
            oriented = frame in cfg.held_frames or frame == cfg.base_frame or frame in cfg.oriented_frames
            out[frame] = FrameTarget(R.copy(), p.copy(), cfg.reference_of.get(frame), frame != cfg.base_frame,
                                     oriented)
        return out

    @property
    def com_target(self) -> np.ndarray | None:
        """CoM target (3,) [m] (z unused without ``com_height``), or None without a CoM task."""
        return self._com_target.copy() if self.config.com else None

    # ------------------------------------------------------------------ residuals and solve
    def task_residuals(self) -> dict[str, TaskResidual]:
        """Every task's residual at the current configuration (computed alike for both backends)."""
        out: dict[str, TaskResidual] = {}
        for frame, target in self.targets().items():
            R, p = self.target_frame_transform(frame)
            position = float(np.linalg.norm(p - target.position)) if target.has_position else None
            angle = float(np.linalg.norm(pin.log3(target.rotation.T @ R))) if target.has_orientation else None
            out[frame] = TaskResidual(position_m=position, orientation_rad=angle)
        if self.config.com:
            axes = 3 if self.config.com_height else 2
            error = self.com()[:axes] - self._com_target[:axes]
            out["com"] = TaskResidual(position_m=float(np.linalg.norm(error)))
        deviation = pin.difference(self.robot.pin_model, self._q_ref, self.q)
        out["posture"] = TaskResidual(deviation=float(np.linalg.norm(deviation)))
        if self.config.damping_cost > 0.0:
            out["damping"] = TaskResidual(deviation=0.0)
        return out

    @property
    def levels(self) -> tuple[tuple[str, ...], ...]:
        """Task names (as in :meth:`task_residuals`) by priority level, level 0 first."""
        return self.config.levels

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
        tasks: Our tasks by name: each held/target frame, the base frame, "com", "posture",
            "damping".
        ik: The underlying ``DiffIK``.
        collision_limit: The collision-avoidance limit (None without collision pairs).
    """

    backend = "qp"

    def _build(self) -> None:
        cfg, m = self.config, self.robot.pin_model
        self.tasks: dict[str, Task] = {}
        for frame in cfg.held_frames:
            self.tasks[frame] = FramePoseTask(frame, m, cfg.held_position_cost, cfg.held_orientation_cost,
                                              lm_damping=cfg.lm_damping, name=frame)
        for frame in cfg.target_frames:
            orientation = cfg.target_orientation_cost if frame in cfg.oriented_frames else 0.0
            reference = cfg.reference_of.get(frame)
            if reference is None:
                self.tasks[frame] = FramePoseTask(frame, m, cfg.target_position_cost, orientation,
                                                  lm_damping=cfg.lm_damping, name=frame)
            else:
                self.tasks[frame] = RelativeFrameTask(frame, reference, m, cfg.target_position_cost,
                                                      orientation, lm_damping=cfg.lm_damping, name=frame)
        if cfg.base_frame is not None:
            self.tasks[cfg.base_frame] = FrameOrientationTask(cfg.base_frame, m, cfg.base_orientation_cost,
                                                              name=cfg.base_frame)
        if cfg.com:
            self.tasks["com"] = ComTask([cfg.com_cost, cfg.com_cost, cfg.com_cost if cfg.com_height else 0.0],
                                        name="com")
        self.tasks["posture"] = PostureTask(m, cfg.posture_cost, name="posture")
        if cfg.damping_cost > 0.0:
            self.tasks["damping"] = DampingTask(m, cfg.damping_cost, name="damping")
        limits: list[Limit] = [self.position_limit]
        speeds = joint_speeds(self.robot, cfg)
        if speeds:
            limits.append(JointVelocityLimit(m, speeds))
        if self.robot.has_floating_base:
            limits.append(FloatingBaseVelocityLimit(m, cfg.base_max_linear_velocity,
                                                    cfg.base_max_angular_velocity))
        self.collision_limit: CollisionAvoidanceLimit | None = None
        if self.collision_pairs is not None:
            self.collision_limit = CollisionAvoidanceLimit(
                self.robot, self.collision_pairs, cfg.min_distance_m, cfg.collision_detection_distance_m,
                cfg.collision_gain)
            limits.append(self.collision_limit)
        level_of = {name: k for k, level in enumerate(cfg.levels) for name in level}
        self.ik = DiffIK(m, list(self.tasks.values()), limits, self.solver, cfg.damping,
                         levels=[level_of[name] for name in self.tasks])

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
        """Centre of mass p_WC (3,) [m] of the robot (the Pinocchio model is the robot alone)."""
        state = self.ik.state
        if not state.with_com:  # no CoM task: compute it on demand
            pin.centerOfMass(state.model, state.data, state.q, False)
        return np.array(state.com())

    def _push_frame_target(self, frame: str, R_XT: np.ndarray, p_XT: np.ndarray) -> None:
        task = self.tasks[frame]
        if isinstance(task, (FramePoseTask, FrameOrientationTask, RelativeFrameTask)):
            task.set_target(pin.SE3(R_XT, p_XT))

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
        return self.ik.advance(self.config.dt)


def joint_positions_by_name(robot: Robot, q: npt.ArrayLike) -> dict[str, list[float]]:
    """``q`` (nq,) split by joint name (free joint: x, y, z, qx, qy, qz, qw)."""
    qa = np.asarray(q, dtype=float)
    return {j.name: qa[j.idx_q : j.idx_q + j.nq].tolist() for j in robot.joints.values()}
