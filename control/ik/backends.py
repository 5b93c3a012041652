"""Whole-body differential IK for any robot: one task set, two backends ("qp" and "mink").

The task set is named by a frozen :class:`WholeBodyIKConfig` (no robot's names are built in):

* held frames F_h (e.g. feet): pose held at the start pose, ``e = log6(X_FT)`` [m, rad];
* target frames F_t (e.g. palms): position targets p_WT [m] in the world (orientation weight 0;
  the target orientation is the start one, as in mink's ``FrameTask``);
* the base frame B (e.g. pelvis): orientation held, ``e = log3(R_BT)`` [rad];
* the centre of mass C (optional): world x and y, ``e = p_WC - p_target`` [m] (z free);
* posture: ``e = q (-) q_ref`` [rad], a regulariser (its residual does not gate convergence);

under joint position limits, optional per-joint speed limits and, for a floating base, base
speed limits. Two backends build that same set:

* ``"qp"`` (:class:`QPWholeBodyIK`): our Pinocchio QP (``DiffIK``), assembled once in
  ``mbctl.control.ik.solve``;
* ``"mink"`` (:class:`MinkWholeBodyIK`): mink over ``robot.mj_model``; frames are MuJoCo sites or
  bodies. States are converted with the model pair's ``StateConverter`` (MuJoCo's free-joint
  linear velocity is in the world frame, Pinocchio's in the base frame).

The two build the same QP, step for step (round-off), with one deliberate difference: on a ball
joint our posture Jacobian is the exact ``pin.dDifference`` block while mink's is the identity,
so with a ball joint away from its posture reference the steps differ by O(cost^2 |e|^2).

Public states (``q`` (nq,), ``v`` (nv,)) are in Pinocchio's convention for both backends.
Residuals are computed the same way for both (world positions, rotation angles from each
backend's own kinematics), so the two are comparable entry by entry.
"""

from __future__ import annotations

import abc
import time
from dataclasses import dataclass
from typing import Any, ClassVar, NamedTuple

import mujoco
import numpy as np
import numpy.typing as npt
import pinocchio as pin

from mbctl.control.exceptions import IKSetupError
from mbctl.control.ik.limits import (
    FloatingBaseVelocityLimit,
    JointPositionLimit,
    JointVelocityLimit,
    Limit,
)
from mbctl.control.ik.solve import DiffIK
from mbctl.control.ik.state import IKState
from mbctl.control.ik.tasks import (
    ComTask,
    FrameOrientationTask,
    FramePoseTask,
    PostureTask,
    Task,
)
from mbctl.robots.model_pair import Robot

#: Backend names accepted by :func:`make_whole_body_ik`.
BACKENDS = ("qp", "mink")

#: Residual entries that regularise and never gate convergence.
REGULARISERS = ("posture",)


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


class WholeBodyIKResult(NamedTuple):
    """Outcome of iterating a whole-body IK backend to convergence.

    Attributes:
        q: Final configuration (nq,), Pinocchio convention.
        converged: Every non-regularising residual within its tolerance.
        stalled: Iteration stopped because the step became negligible before convergence (a
            local minimum: the target is out of reach, or the pose is singular for it).
        iterations: Steps taken.
        residuals: Per task, residual norms by quantity (``"position [m]"``,
            ``"orientation [rad]"``, ``"deviation [rad]"`` for the posture regulariser), at ``q``.
        step_norms: Infinity norm of each tangent step (iterations,) [rad or m].
        iteration_times_s: Wall time of each step (iterations,) [s]: kinematics, QP, integration.
        wall_time_s: Wall time of the whole loop [s].
    """

    q: np.ndarray
    converged: bool
    stalled: bool
    iterations: int
    residuals: dict[str, dict[str, float]]
    step_norms: np.ndarray
    iteration_times_s: np.ndarray
    wall_time_s: float


def mujoco_frame_type(robot: Robot, frame: str) -> str:
    """``"site"`` or ``"body"``: what MuJoCo object ``frame`` names (sites first).

    Raises:
        IKSetupError: Neither a site nor a body; the message lists the available names.
    """
    if frame in robot.sites:
        return "site"
    if frame in robot.bodies:
        return "body"
    from mbctl.exceptions import unknown_name_message

    raise IKSetupError(unknown_name_message("IK frame (a MuJoCo site or body)", frame,
                                            [*robot.sites, *robot.bodies]))


def _hinge_names(robot: Robot) -> list[str]:
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
    def _advance(self) -> float:
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
            from mbctl.exceptions import unknown_name_message

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
    def residuals(self) -> dict[str, dict[str, float]]:
        """Residual norms of every task at the current configuration (same for both backends)."""
        out: dict[str, dict[str, float]] = {}
        cfg = self.config
        for frame in cfg.frames:
            R, p = self.frame_transform(frame)
            R_T, p_T = self._targets[frame]
            entry: dict[str, float] = {}
            if frame != cfg.base_frame:
                entry["position [m]"] = float(np.linalg.norm(p - p_T))
            if frame in cfg.held_frames or frame == cfg.base_frame:
                entry["orientation [rad]"] = float(np.linalg.norm(pin.log3(R_T.T @ R)))
            out[frame] = entry
        if cfg.com:
            out["com"] = {"position [m]": float(np.linalg.norm(self.com()[:2] - self._com_target[:2]))}
        deviation = pin.difference(self.robot.pin_model, self._q_ref, self.q)
        out["posture"] = {"deviation [rad]": float(np.linalg.norm(deviation))}
        return out

    def solve(
        self,
        q0: npt.ArrayLike,
        tol: float = 1e-3,
        tol_rad: float | None = None,
        max_iters: int = 50,
        step_tol: float = 1e-6,
    ) -> WholeBodyIKResult:
        """Iterate from ``q0`` (nq,) until every task meets its tolerance.

        An unreachable target is not an error: iteration stops when the step becomes negligible
        (``stalled``) and the residuals say how far each task is from its target.

        Args:
            q0: Initial configuration (nq,), Pinocchio convention.
            tol: Position tolerance [m].
            tol_rad: Orientation tolerance [rad] (default ``10 * tol``).
            max_iters: Maximum number of steps.
            step_tol: Stop when the step's inf-norm falls below this [rad or m].

        Raises:
            IKSetupError: Non-positive tolerances or iteration count.
            IKInfeasible: A step's QP has no solution (qp backend).
        """
        tol_rad = 10.0 * tol if tol_rad is None else tol_rad
        if not (tol > 0.0 and tol_rad > 0.0 and step_tol > 0.0) or int(max_iters) < 1:
            raise IKSetupError(
                f"tol, tol_rad, step_tol must be > 0 and max_iters >= 1; got tol={tol!r}, "
                f"tol_rad={tol_rad!r}, step_tol={step_tol!r}, max_iters={max_iters!r}"
            )
        t0 = time.perf_counter()
        self.update(q0)
        steps: list[float] = []
        times: list[float] = []
        converged = stalled = False
        for it in range(int(max_iters) + 1):
            res = self.residuals()
            converged = residuals_within(res, tol, tol_rad)
            if converged or stalled or it == int(max_iters):
                break
            t = time.perf_counter()
            steps.append(self._advance())
            times.append(time.perf_counter() - t)
            stalled = steps[-1] < step_tol
        return WholeBodyIKResult(self.q, converged, stalled and not converged, len(steps), res,
                                 np.array(steps), np.array(times), time.perf_counter() - t0)


def residuals_within(residuals: dict[str, dict[str, float]], tol: float, tol_rad: float) -> bool:
    """Every non-regularising residual within ``tol`` [m] (or ``tol_rad`` [rad] for angles)."""
    return all(
        value <= (tol_rad if "[rad]" in key else tol)
        for task, values in residuals.items() if task not in REGULARISERS
        for key, value in values.items()
    )


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
            speeds = {n: cfg.joint_max_velocity for n in _hinge_names(self.robot)}
            limits.append(JointVelocityLimit(m, speeds))
        if self.robot.has_floating_base:
            limits.append(FloatingBaseVelocityLimit(m, cfg.base_max_linear_velocity,
                                                    cfg.base_max_angular_velocity))
        self.ik = DiffIK(m, list(self.tasks.values()), limits, self.solver, cfg.damping)

    @property
    def state(self) -> IKState:
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

    def _advance(self) -> float:
        out = self.ik.solve_step(self.config.dt)
        self.ik.update(pin.integrate(self.robot.pin_model, self.ik.state.q, out.dq))
        return float(np.max(np.abs(out.dq)))


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
            self.tasks[frame] = mink.FrameTask(frame, self._types[frame], cfg.target_position_cost, 0.0,
                                               lm_damping=cfg.lm_damping)
        if cfg.base_frame is not None:
            self.tasks[cfg.base_frame] = mink.FrameTask(cfg.base_frame, self._types[cfg.base_frame], 0.0,
                                                        cfg.base_orientation_cost)
        if cfg.com:
            _check_mink_com(self.robot)
            self.tasks["com"] = mink.ComTask(cost=[cfg.com_cost, cfg.com_cost, 0.0])
        self.tasks["posture"] = mink.PostureTask(m, cost=cfg.posture_cost)
        self._task_list = list(self.tasks.values())
        self.limits: list[Any] = [mink.ConfigurationLimit(m, gain=cfg.joint_position_gain)]
        if cfg.joint_max_velocity is not None:
            self.limits.append(mink.VelocityLimit(
                m, {n: cfg.joint_max_velocity for n in _hinge_names(self.robot)}))
        if self.robot.has_floating_base:
            self.limits.append(mink.FreeJointVelocityLimit(m, cfg.base_max_linear_velocity,
                                                           cfg.base_max_angular_velocity))

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

    def _push_frame_target(self, frame: str, R_WT: np.ndarray, p_WT: np.ndarray) -> None:
        mink = self._mink
        self.tasks[frame].set_target(
            mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(R_WT), np.array(p_WT)))

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

    def _advance(self) -> float:
        v = self.step_mj()
        self.configuration.integrate_inplace(v, self.config.dt)
        return float(np.max(np.abs(v))) * self.config.dt


def _check_mink_com(robot: Robot) -> None:
    """Refuse a CoM task mink would get wrong: its ComTask is the subtree CoM of MuJoCo body 1.

    Raises:
        IKSetupError: Body 1's subtree does not hold the whole model's mass (a scene that puts
            another body before the robot); the message names the body, the masses and ``"qp"``.
    """
    m = robot.mj_model
    total, first = float(m.body_subtreemass[0]), float(m.body_subtreemass[1])
    if not np.isclose(first, total, rtol=1e-9, atol=0.0):
        raise IKSetupError(
            f"backend 'mink' cannot hold the CoM of {robot.name!r}: mink's ComTask uses the subtree "
            f"of MuJoCo body 1 ({mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, 1)!r}, {first:.6g} kg), "
            "but the model's mass is "
            f"{total:.6g} kg (the scene puts another body before the robot); use backend 'qp', or "
            "put the robot first in the scene"
        )


#: Backend name -> class.
BACKEND_CLASSES: dict[str, type[WholeBodyIK]] = {"qp": QPWholeBodyIK, "mink": MinkWholeBodyIK}


def make_whole_body_ik(
    backend: str,
    robot: Robot,
    config: WholeBodyIKConfig,
    q_ref: npt.ArrayLike,
    solver: str = "daqp",
) -> WholeBodyIK:
    """Build the task set ``config`` on ``backend`` ("qp" or "mink").

    Args:
        backend: "qp" (our Pinocchio QP) or "mink".
        robot: The model pair.
        config: Task set, weights and limits.
        q_ref: Start configuration (nq,), Pinocchio convention: the first targets.
        solver: qpsolvers backend name.

    Raises:
        IKSetupError: Unknown backend (the message names the alternatives), or a bad task set.
    """
    if backend not in BACKEND_CLASSES:
        raise IKSetupError(f"IK backend {backend!r} is unknown; choose one of {', '.join(BACKENDS)}")
    return BACKEND_CLASSES[backend](robot, config, q_ref, solver)


def joint_positions_by_name(robot: Robot, q: npt.ArrayLike) -> dict[str, list[float]]:
    """``q`` (nq,) split by joint name (free joint: x, y, z, qx, qy, qz, qw)."""
    qa = np.asarray(q, dtype=float)
    return {j.name: qa[j.idx_q : j.idx_q + j.nq].tolist() for j in robot.joints.values()}
