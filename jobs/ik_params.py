"""What ``mbctl ik`` solves (:class:`IKParams`), and the parsing of its command-line values.

Targets: ``FRAME=X,Y,Z`` (a world position [m]), ``FRAME=X,Y,Z,QW,QX,QY,QZ`` (a full pose: the
quaternion in (w, x, y, z) order, normalised), and ``FRAME@REF=...``: the same pose in frame REF,
held relative to REF as it moves. ``--orientation FRAME=QW,QX,QY,QZ`` sets an orientation alone
(the position target is then the start position unless a ``--target`` gives one). With
``--relative``, positions are offsets [m] from the frame's start position (in the world, or in REF);
orientations are always absolute.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

from mbctl.control.exceptions import IKSetupError
from mbctl.control.ik import BACKENDS
from mbctl.robots.collision import CollisionPair
from mbctl.robots.exceptions import CollisionPairError
from mbctl.robots.registry import KNOWN_ROBOTS

#: QP backends of qpsolvers that ``mbctl ik`` offers.
SOLVERS = ("daqp", "osqp")

#: Orientation tolerance [rad] per metre of position tolerance.
RAD_PER_M_TOL = 10.0

#: Largest ``--damping`` weight [cost]/[rad]: 20 times the targets' 5 [cost]/[m]. A step then
#: closes about (5 / 100)^2 = 0.25 % of a target's error (Jacobian gains near 1 m/rad), so the
#: iteration cap ends the solve; far above it the damping is the whole cost: at 1e4 every step
#: vanished ("stalled", blamed on the target) and at 1e8 the QP solver failed (daqp, iteration limit).
MAX_DAMPING_COST = 100.0


class TargetSpec(NamedTuple):
    """One frame's target as given on the command line.

    Attributes:
        frame: MuJoCo site or body.
        position: (x, y, z) [m] in the world or ``reference``, or None (keep the start position).
        quat_wxyz: Orientation (w, x, y, z), unit norm, or None (orientation free, or held for
            frames whose orientation the task set holds).
        reference: Frame the pose is given in (and held relative to), or None for the world.
    """

    frame: str
    position: tuple[float, float, float] | None = None
    quat_wxyz: tuple[float, float, float, float] | None = None
    reference: str | None = None


@dataclass(frozen=True)
class IKParams:
    """What ``mbctl ik`` solves.

    Attributes:
        robot: Known robot name or MJCF robot file.
        targets: (frame, (x, y, z) [m]) position targets, world frame (offsets with ``relative``).
        com_xy: CoM target (x, y) or (x, y, z) [m] in the world, or None (the name is historical:
            three values also hold the height).
        relative: Target positions are offsets from the start pose [m].
        tol_m: Position tolerance [m]; orientations get ``RAD_PER_M_TOL * tol_m`` [rad].
        max_iters: Iteration cap.
        solver: qpsolvers backend (``SOLVERS``).
        backend: IK backend (``BACKENDS``: "qp" or "mink").
        keyframe: Start keyframe (None: "stand" for the G1, else "home" when the robot has one,
            else the neutral pose).
        scene: Scene MJCF for MuJoCo that includes the robot (default: the robot's own).
        model_dir: Explicit Menagerie model directory for a known robot.
        roots: Bodies whose trees are the robot (default: the trees the actuators drive).
        poses: Full-pose and relative targets (:class:`TargetSpec`), beside ``targets``.
        priorities: (task, level) pairs (a target frame or "com"; 0 is the highest level); tasks
            not named go one level below the lowest named level.
        avoid_collisions: Avoid the default collision set (the G1's self-collision set; for other
            robots every robot geom against every other, adjacent bodies excluded).
        collision_pairs: More pairs to avoid, "A:B" (see ``mbctl.robots.collision``).
        min_distance_m: Minimum distance [m] of every avoided (and checked) pair.
        max_velocities: (joint, speed [rad/s or m/s]) per-joint velocity limits.
        damping_cost: Weight [cost]/[rad] of a minimum-motion task (0: none).
        clip_start: Clip a start outside the joint limits into them (else refused).
    """

    robot: str
    targets: tuple[tuple[str, tuple[float, float, float]], ...] = ()
    com_xy: tuple[float, ...] | None = None
    relative: bool = False
    tol_m: float = 1e-3
    max_iters: int = 50
    solver: str = "daqp"
    backend: str = "qp"
    keyframe: str | None = None
    scene: str | None = None
    model_dir: str | None = None
    roots: tuple[str, ...] = ()
    poses: tuple[TargetSpec, ...] = ()
    priorities: tuple[tuple[str, int], ...] = ()
    avoid_collisions: bool = False
    collision_pairs: tuple[str, ...] = ()
    min_distance_m: float = 0.005
    max_velocities: tuple[tuple[str, float], ...] = ()
    damping_cost: float = 0.0
    clip_start: bool = False

    def __post_init__(self) -> None:
        """Validate every value (IKSetupError naming the bad one)."""
        specs = self.specs
        if not specs and self.com_xy is None:
            raise IKSetupError("Give at least one --target FRAME=X,Y,Z (or --orientation, or --com X,Y).")
        if self.solver not in SOLVERS:
            raise IKSetupError(f"solver must be one of {', '.join(SOLVERS)}; got {self.solver!r}")
        if self.backend not in BACKENDS:
            raise IKSetupError(f"backend must be one of {', '.join(BACKENDS)}; got {self.backend!r}")
        if not (math.isfinite(self.tol_m) and self.tol_m > 0):
            raise IKSetupError(f"tol must be a positive length (m); got {self.tol_m!r}")
        if int(self.max_iters) < 1:
            raise IKSetupError(f"max_iters must be >= 1; got {self.max_iters!r}")
        for spec in specs:
            if spec.position is not None and (len(spec.position) != 3
                                              or not all(math.isfinite(v) for v in spec.position)):
                raise IKSetupError(f"target of {spec.frame!r} must be 3 finite numbers (m); "
                                   f"got {spec.position!r}")
        if self.com_xy is not None and (len(self.com_xy) not in (2, 3) or
                                        not all(math.isfinite(v) for v in self.com_xy)):
            raise IKSetupError(f"com must be 2 or 3 finite numbers (m); got {self.com_xy!r}")
        if self.model_dir is not None and self.robot not in KNOWN_ROBOTS:
            raise IKSetupError(
                f"--model-dir applies only to a known robot ({', '.join(KNOWN_ROBOTS)}); "
                f"{self.robot!r} is a path: drop --model-dir"
            )
        if not (math.isfinite(self.min_distance_m) and -0.05 <= self.min_distance_m < 0.1):
            raise IKSetupError(f"min distance must be in [-0.05, 0.1) m; got {self.min_distance_m!r}")
        if not (math.isfinite(self.damping_cost) and 0.0 <= self.damping_cost <= MAX_DAMPING_COST):
            raise IKSetupError(f"--damping must be a weight in [0, {MAX_DAMPING_COST:g}] [cost]/[rad] (the "
                               f"targets' weight is 5; above {MAX_DAMPING_COST:g} the damping stops every "
                               f"step and the QP fails); got {self.damping_cost!r}")
        try:
            for text in self.collision_pairs:
                CollisionPair.parse(text)
        except CollisionPairError as exc:
            raise IKSetupError(str(exc)) from None

    @property
    def tol_rad(self) -> float:
        """Orientation tolerance [rad]."""
        return RAD_PER_M_TOL * self.tol_m

    @property
    def specs(self) -> tuple[TargetSpec, ...]:
        """Every frame's target, one per frame (positions, orientations and references merged).

        Raises:
            IKSetupError: Two different positions, orientations or references for one frame.
        """
        given = [TargetSpec(name, (float(xyz[0]), float(xyz[1]), float(xyz[2])) if len(xyz) == 3 else None)
                 for name, xyz in self.targets]
        for (name, xyz), spec in zip(self.targets, given, strict=True):
            if spec.position is None:
                raise IKSetupError(f"target of {name!r} must be 3 finite numbers (m); got {xyz!r}")
        return _merge([*given, *self.poses])

    @property
    def pairs(self) -> tuple[CollisionPair, ...]:
        """The ``--collision-pair`` values, parsed."""
        return tuple(CollisionPair.parse(text) for text in self.collision_pairs)

    @property
    def avoids(self) -> bool:
        """Whether the IK avoids collisions (the default set, or named pairs)."""
        return self.avoid_collisions or bool(self.collision_pairs)


def _merge(specs: list[TargetSpec]) -> tuple[TargetSpec, ...]:
    """One spec per frame: a position and an orientation given separately are merged.

    Raises:
        IKSetupError: Two different positions, orientations or references for one frame.
    """
    out: dict[str, TargetSpec] = {}
    for spec in specs:
        old = out.get(spec.frame)
        if old is None:
            out[spec.frame] = spec
            continue
        for part in ("position", "quat_wxyz", "reference"):
            if getattr(old, part) is not None and getattr(spec, part) not in (None, getattr(old, part)):
                what = part.replace("quat_wxyz", "orientation")
                raise IKSetupError(f"frame {spec.frame!r} has more than one {what} target; give one each")
        out[spec.frame] = TargetSpec(spec.frame, old.position or spec.position,
                                     old.quat_wxyz or spec.quat_wxyz, old.reference or spec.reference)
    return tuple(out.values())


# ---------------------------------------------------------------------- command-line values
def parse_numbers(text: str, counts: tuple[int, ...], what: str, form: str) -> tuple[float, ...]:
    """``"a,b,c"`` -> floats, as many as one of ``counts``; IKSetupError naming ``what`` otherwise."""
    try:
        values = tuple(float(p.strip()) for p in text.split(","))
    except ValueError:
        values = ()
    if len(values) not in counts or not all(math.isfinite(v) for v in values):
        counted = " or ".join(map(str, counts))
        raise IKSetupError(f"{what} must be {counted} finite numbers as {form}; got {text!r}")
    return values


def _unit_quat(values: tuple[float, ...], what: str) -> tuple[float, float, float, float]:
    norm = math.sqrt(sum(v * v for v in values))
    if norm < 1e-9:
        raise IKSetupError(f"{what}: the quaternion QW,QX,QY,QZ must not be zero; got {values!r}")
    w, x, y, z = (v / norm for v in values)
    return w, x, y, z


def _name_and_values(text: str, option: str, example: str) -> tuple[str, str]:
    name, sep, values = text.partition("=")
    if not sep or not name.strip():
        raise IKSetupError(f"{option} must look like {example}; got {text!r}")
    return name.strip(), values


def _frame_and_reference(name: str, option: str, text: str) -> tuple[str, str | None]:
    """``FRAME`` or ``FRAME@REF`` -> (frame, reference or None); IKSetupError if a side is empty.

    An empty reference (``FRAME@=...``) is refused, never read as the world.
    """
    frame, at, reference = (part.strip() for part in name.partition("@"))
    if not frame or (at and not reference):
        raise IKSetupError(f"{option} FRAME@REF needs both names (REF: a site or body the pose is "
                           f"given in; leave out @REF for the world); got {text!r}")
    return frame, reference or None


def parse_target(text: str) -> TargetSpec:
    """``FRAME[@REF]=X,Y,Z[,QW,QX,QY,QZ]`` -> TargetSpec; IKSetupError if malformed."""
    name, values = _name_and_values(text, "--target",
                                    "FRAME=X,Y,Z[,QW,QX,QY,QZ] (e.g. left_palm=0.3,0.2,0.9)")
    frame, reference = _frame_and_reference(name, "--target", text)
    numbers = parse_numbers(values, (3, 7), f"--target {name} (m, then an optional quaternion)",
                            "X,Y,Z or X,Y,Z,QW,QX,QY,QZ")
    quat = _unit_quat(numbers[3:], f"--target {name}") if len(numbers) == 7 else None
    return TargetSpec(frame, (numbers[0], numbers[1], numbers[2]), quat, reference)


def parse_orientation(text: str) -> TargetSpec:
    """``FRAME[@REF]=QW,QX,QY,QZ`` -> TargetSpec (orientation only)."""
    name, values = _name_and_values(text, "--orientation", "FRAME=QW,QX,QY,QZ (e.g. left_palm=1,0,0,0)")
    frame, reference = _frame_and_reference(name, "--orientation", text)
    numbers = parse_numbers(values, (4,), f"--orientation {name}", "QW,QX,QY,QZ")
    quat = _unit_quat(numbers, f"--orientation {name}")
    return TargetSpec(frame, None, quat, reference)


def parse_priority(text: str) -> tuple[str, int]:
    """``NAME=LEVEL`` -> (name, level); IKSetupError if malformed."""
    name, values = _name_and_values(text, "--priority", "NAME=LEVEL (e.g. com=0, left_palm=1)")
    try:
        level = int(values.strip())
    except ValueError:
        raise IKSetupError(f"--priority {name}: the level must be an integer >= 0; got {values!r}") from None
    if level < 0:
        raise IKSetupError(f"--priority {name}: the level must be >= 0 (0 is the highest); got {level}")
    return name, level


def parse_velocity(text: str) -> tuple[str, float]:
    """``JOINT=SPEED`` [rad/s or m/s] -> (joint, speed); IKSetupError if malformed."""
    name, values = _name_and_values(text, "--max-velocity", "JOINT=SPEED (e.g. left_elbow_joint=1.0)")
    speed = parse_numbers(values, (1,), f"--max-velocity {name} (rad/s)", "SPEED")[0]
    if speed <= 0.0:
        raise IKSetupError(f"--max-velocity {name} must be > 0 (rad/s); got {speed!r}")
    return name, speed
