"""The whole-body IK task set as a frozen config: frames by role, weights, limits, priorities, collisions.

No robot's names are built in: the caller names the frames (MuJoCo sites or bodies of the robot).
Task names, used for residuals and priorities, are the frame names, ``"com"``, ``"posture"`` and
``"damping"``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from mbctl.control.exceptions import IKSetupError
from mbctl.exceptions import unknown_name_message
from mbctl.robots.collision import CollisionPair


@dataclass(frozen=True)
class WholeBodyIKConfig:
    """The whole-body task set (frame names) with its weights, limits, priorities and collision pairs.

    Attributes:
        held_frames: Frames whose start pose is held (MuJoCo sites or bodies).
        target_frames: Frames that get position targets (MuJoCo sites or bodies); their
            orientation is free unless they are in ``oriented_frames``.
        oriented_frames: Target frames that also get an orientation target (full pose).
        relative_targets: ``(frame, reference)`` pairs: that target frame's target is a pose in
            the reference frame (a MuJoCo site or body that may move), held relative to it.
        base_frame: Frame whose start orientation is held, or None.
        com: Add a CoM task on world x and y.
        com_height: The CoM task also holds the height (world z).
        held_position_cost: [cost]/[m].
        held_orientation_cost: [cost]/[rad].
        target_position_cost: [cost]/[m].
        target_orientation_cost: [cost]/[rad] (oriented target frames only).
        com_cost: [cost]/[m] per CoM axis held.
        base_orientation_cost: [cost]/[rad].
        posture_cost: [cost]/[rad].
        damping_cost: Weight [cost]/[rad] of a minimum-motion (damping) task; 0: none.
        lm_damping: Levenberg-Marquardt scale [-] on held and target frames.
        damping: Global LM damping on all dofs [cost].
        joint_position_gain: Fraction in (0, 1] of the distance to a joint limit per step.
        joint_max_velocity: Per-joint speed bound [rad/s] (trust region ``v dt`` per step), or
            None for no per-joint speed bound.
        joint_max_velocities: ``(joint, speed [rad/s or m/s])`` overrides of
            ``joint_max_velocity`` for named 1-dof joints.
        base_max_linear_velocity: Base linear speed bound per axis [m/s] (floating base only).
        base_max_angular_velocity: Base angular speed bound per axis [rad/s] (floating base only).
        dt: Step duration [s] the velocity bounds are scaled by.
        priorities: ``(task, level)`` pairs: level 0 is solved first, each next level within the
            optimum of the levels above (a lexicographic solve). Tasks not named go one level
            below the lowest named one (``max(level) + 1``: ``com=0`` alone puts the CoM above
            every other task); posture and damping are always in the last level. Levels are
            renumbered 0, 1, ... in order. Empty: one weighted level.
        collision_pairs: Geom pairs kept apart (:class:`~mbctl.robots.collision.CollisionPair`).
        min_distance_m: Minimum distance [m] of every collision pair.
        collision_detection_distance_m: Pairs farther apart than this [m] are not constrained.
        collision_gain: Fraction in (0, 1] of a pair's gap a step may close.
    """

    held_frames: tuple[str, ...] = ()
    target_frames: tuple[str, ...] = ()
    oriented_frames: tuple[str, ...] = ()
    relative_targets: tuple[tuple[str, str], ...] = ()
    base_frame: str | None = None
    com: bool = False
    com_height: bool = False
    held_position_cost: float = 10.0
    held_orientation_cost: float = 1.0
    target_position_cost: float = 5.0
    target_orientation_cost: float = 1.0
    com_cost: float = 10.0
    base_orientation_cost: float = 10.0
    posture_cost: float = 1e-2
    damping_cost: float = 0.0
    lm_damping: float = 1.0
    damping: float = 1e-3
    joint_position_gain: float = 0.95
    joint_max_velocity: float | None = 2.0
    joint_max_velocities: tuple[tuple[str, float], ...] = ()
    base_max_linear_velocity: float = 1.0
    base_max_angular_velocity: float = 2.0
    dt: float = 1.0
    priorities: tuple[tuple[str, int], ...] = ()
    collision_pairs: tuple[CollisionPair, ...] = ()
    min_distance_m: float = 0.005
    collision_detection_distance_m: float = 0.1
    collision_gain: float = 0.85

    def __post_init__(self) -> None:
        """Validate names and ranges.

        Raises:
            IKSetupError: A frame with two roles, no task, a negative weight, a non-positive
                bound, a priority of an unknown task, or a bad collision setting.
        """
        for name in ("held_frames", "target_frames", "oriented_frames"):
            object.__setattr__(self, name, tuple(getattr(self, name)))
        object.__setattr__(self, "relative_targets",
                           tuple((str(f), str(r)) for f, r in self.relative_targets))
        object.__setattr__(self, "joint_max_velocities",
                           tuple((str(j), float(v)) for j, v in self.joint_max_velocities))
        object.__setattr__(self, "priorities", tuple((str(t), int(k)) for t, k in self.priorities))
        object.__setattr__(self, "collision_pairs", tuple(
            p if isinstance(p, CollisionPair) else CollisionPair(*p) for p in self.collision_pairs))
        self._check_frames()
        self._check_numbers()
        names = self.task_names
        for task, level in self.priorities:
            if task not in names or task in ("posture", "damping"):
                allowed = [n for n in names if n not in ("posture", "damping")]
                raise IKSetupError(unknown_name_message("task to prioritise (a target frame or com)", task,
                                                        allowed))
            if level < 0:
                raise IKSetupError(f"priority level of {task!r} must be >= 0 (0 is the highest); got {level}")
        prioritised = [t for t, _ in self.priorities]
        repeated = sorted({t for t in prioritised if prioritised.count(t) > 1})
        if repeated:
            raise IKSetupError(f"tasks {repeated} have more than one priority; give one each")

    def _check_frames(self) -> None:
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
        for frame in (*self.oriented_frames, *(f for f, _ in self.relative_targets)):
            if frame not in self.target_frames:
                raise IKSetupError(unknown_name_message("target frame (for an orientation or a relative "
                                                        "target)", frame, self.target_frames))
        relative = [f for f, _ in self.relative_targets]
        if len(set(relative)) != len(relative):
            raise IKSetupError(f"a target frame is relative to one reference frame; "
                               f"got {self.relative_targets}")
        for frame, reference in self.relative_targets:
            if frame == reference:
                raise IKSetupError(f"target frame {frame!r} cannot be relative to itself")
        if self.com_height and not self.com:
            raise IKSetupError("com_height needs the CoM task (com=True)")

    def _check_numbers(self) -> None:
        for name in ("held_position_cost", "held_orientation_cost", "target_position_cost",
                     "target_orientation_cost", "com_cost", "base_orientation_cost", "posture_cost",
                     "damping_cost", "lm_damping", "damping"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise IKSetupError(f"WholeBodyIKConfig.{name} must be >= 0; got {value!r}")
        positive = ["base_max_linear_velocity", "base_max_angular_velocity", "dt"]
        if self.joint_max_velocity is not None:
            positive.append("joint_max_velocity")
        for name in positive:
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise IKSetupError(f"WholeBodyIKConfig.{name} must be > 0; got {value!r}")
        for joint, speed in self.joint_max_velocities:
            if not (math.isfinite(speed) and speed > 0.0):
                raise IKSetupError(f"max velocity of joint {joint!r} must be > 0 [rad/s]; got {speed!r}")
        if not 0.0 < self.joint_position_gain <= 1.0:
            raise IKSetupError(
                f"WholeBodyIKConfig.joint_position_gain must be in (0, 1]; "
                f"got {self.joint_position_gain!r}"
            )
        if not 0.0 < self.collision_gain <= 1.0:
            raise IKSetupError(f"WholeBodyIKConfig.collision_gain must be in (0, 1]; "
                               f"got {self.collision_gain!r}")
        if not (math.isfinite(self.min_distance_m) and math.isfinite(self.collision_detection_distance_m)
                and self.collision_detection_distance_m > self.min_distance_m):
            raise IKSetupError(
                f"collision detection distance ({self.collision_detection_distance_m!r} m) must exceed the "
                f"minimum distance ({self.min_distance_m!r} m), both finite")

    @property
    def frames(self) -> tuple[str, ...]:
        """Every frame the task set names (held, target, base)."""
        base = (self.base_frame,) if self.base_frame is not None else ()
        return (*self.held_frames, *self.target_frames, *base)

    @property
    def reference_of(self) -> dict[str, str]:
        """The reference frame of each relative target frame."""
        return dict(self.relative_targets)

    @property
    def task_names(self) -> tuple[str, ...]:
        """Every task's name, in build order: frames, "com", "posture", "damping"."""
        return (*self.frames, *(("com",) if self.com else ()), "posture",
                *(("damping",) if self.damping_cost > 0.0 else ()))

    @property
    def unnamed_level(self) -> int:
        """The level (before renumbering) of tasks not named in ``priorities``.

        One below the lowest named level, ``max(level) + 1`` (0 without priorities).
        """
        return max((k for _, k in self.priorities), default=-1) + 1

    @property
    def levels(self) -> tuple[tuple[str, ...], ...]:
        """Task names by priority level (level 0 first; one level without priorities).

        Tasks not named in ``priorities`` are at :attr:`unnamed_level`, below every named one.
        """
        given = dict(self.priorities)
        unnamed = self.unnamed_level
        regularisers = {"posture", "damping"}
        ranks = sorted({given.get(t, unnamed) for t in self.task_names if t not in regularisers})
        if not ranks:
            ranks = [0]
        level_of = {t: ranks.index(given.get(t, unnamed)) for t in self.task_names if t not in regularisers}
        last = len(ranks) - 1
        return tuple(tuple(t for t in self.task_names if level_of.get(t, last) == k) for k in range(last + 1))
