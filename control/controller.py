"""The controller protocol, reference types, and the joint-to-actuator map torque controllers share.

A controller is pure: ``compute(state, reference) -> Command`` reads a measured
:class:`~mbctl.robots.interface.RobotState` and a reference and returns a typed command
(torque, position target or velocity target); ``reset()`` clears internal state (saturation
counts, integrators). Controllers never step the plant; :func:`mbctl.control.loop.run` does,
through any :class:`~mbctl.robots.interface.RobotInterface`.

Joint-space controllers act on a tuple of *controlled joints*: 1-dof joints driven by an
actuator, by default every actuated joint in actuator order. ``JointMap`` resolves, once, where
each controlled joint sits in q and v (Pinocchio convention) and which actuator drives it, so a
floating-base robot gets torques for its actuated joints only.

``ControllerBase`` holds the plumbing every controller shares (joint map, output clipping,
command names, the analytic model and its checks); ``JointFeedbackController`` adds per-joint
gains and the feedback ``kp e + kd de`` the joint-space laws build on.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple, Protocol, TypeVar, runtime_checkable

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from mbctl.control.exceptions import ControllerSetupError, ReferenceMismatch
from mbctl.control.gains import PDGains
from mbctl.robots.commands import Command, CommandKind, kind_mismatch
from mbctl.robots.fastmath import SMALL_VECTOR_MAX, any_outside
from mbctl.robots.interface import RobotState
from mbctl.robots.model_pair import Robot


class JointReference(NamedTuple):
    """Desired joint motion over a controller's joints (in the controller's joint order).

    Built without copying or validation, so a control loop can make one per cycle from views of
    pre-sampled arrays; use :func:`joint_reference` to validate user input once.

    Attributes:
        q: Desired positions (n,) [rad] (or [m] for slide joints).
        v: Desired velocities (n,) [rad/s].
        a: Desired accelerations (n,) [rad/s^2] (feed-forward; PD laws ignore it).
    """

    q: np.ndarray
    v: np.ndarray
    a: np.ndarray


class TaskReference(NamedTuple):
    """Desired motion of a point in the world frame W, over a controller's task axes.

    Attributes:
        p: Desired position p_WS (k,) [m].
        v: Desired velocity v_WS (k,) [m/s].
        a: Desired acceleration a_WS (k,) [m/s^2].
    """

    p: np.ndarray
    v: np.ndarray
    a: np.ndarray


def _checked(name: str, x: npt.ArrayLike | None, n: int) -> np.ndarray:
    if x is None:
        return np.zeros(n)
    try:
        arr = np.array(x, dtype=float, ndmin=1)
    except (TypeError, ValueError) as exc:
        raise ReferenceMismatch(f"reference {name} must be a numeric vector; got {x!r}") from exc
    if arr.shape != (n,):
        raise ReferenceMismatch(f"reference {name} must have shape ({n},); got {arr.shape}")
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        raise ReferenceMismatch(f"reference {name} must be finite; entries {bad.tolist()} are not")
    arr.setflags(write=False)
    return arr


def _checked_triple(
    name: str, x: npt.ArrayLike, v: npt.ArrayLike | None, a: npt.ArrayLike | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    x_arr = _checked(name, x, int(np.size(x)))
    n = x_arr.size
    return x_arr, _checked("v", v, n), _checked("a", a, n)


def joint_reference(
    q: npt.ArrayLike, v: npt.ArrayLike | None = None, a: npt.ArrayLike | None = None
) -> JointReference:
    """A validated, read-only JointReference; v and a default to zeros (a set-point).

    Raises:
        ReferenceMismatch: Shapes differ from q's, or non-finite values.
    """
    return JointReference(*_checked_triple("q", q, v, a))


def task_reference(
    p: npt.ArrayLike, v: npt.ArrayLike | None = None, a: npt.ArrayLike | None = None
) -> TaskReference:
    """A validated, read-only TaskReference; v and a default to zeros.

    Raises:
        ReferenceMismatch: Shapes differ from p's, or non-finite values.
    """
    return TaskReference(*_checked_triple("p", p, v, a))


#: The reference a controller takes (JointReference or TaskReference); contravariant because a
#: controller is a consumer of references.
RefT_contra = TypeVar("RefT_contra", contravariant=True)


@runtime_checkable
class Controller(Protocol[RefT_contra]):
    """A pure control law: state and reference in, typed command out."""

    def reset(self) -> None:
        """Clear internal state (saturation counts, integrators) before a new run."""

    def compute(self, state: RobotState, reference: RefT_contra) -> Command:
        """The command for ``state`` (Pinocchio convention) tracking ``reference``."""


@dataclass(frozen=True, eq=False)
class JointMap:
    """Controlled joints, where they sit in q and v, and the actuators driving them.

    Attributes:
        joints: Controlled joint names (n,), 1-dof each.
        actuators: Actuator driving each joint (n,).
        idx_q: Index of each joint in q (n,), Pinocchio convention (read-only).
        idx_v: Index of each joint in v (n,) (read-only).
        actuator_index: ctrl index of each actuator (n,) (read-only).
        covers_all_actuators: The actuators are every actuator, in ctrl order (so a command can
            be a full vector, the cheapest to bind).
        tau_low: Lowest torque [N m] (or force [N]) each actuator can apply (n,).
        tau_high: Highest torque [N m] (or force [N]) each actuator can apply (n,).
    """

    joints: tuple[str, ...]
    actuators: tuple[str, ...]
    idx_q: np.ndarray
    idx_v: np.ndarray
    actuator_index: np.ndarray
    covers_all_actuators: bool
    tau_low: np.ndarray
    tau_high: np.ndarray

    @property
    def size(self) -> int:
        """Number of controlled joints."""
        return len(self.joints)

    @property
    def q_selector(self) -> slice | np.ndarray:
        """Selects the joints from q: a slice when the indices are contiguous (a view, no copy)."""
        return _selector(self.idx_q)

    @property
    def v_selector(self) -> slice | np.ndarray:
        """Selects the joints from v: a slice when the indices are contiguous (a view, no copy)."""
        return _selector(self.idx_v)

    @property
    def command_names(self) -> tuple[str, ...] | None:
        """Names for a command over these actuators (None: a full vector)."""
        return None if self.covers_all_actuators else self.actuators

    @classmethod
    def from_robot(cls, robot: Robot, joints: Sequence[str] | None = None) -> JointMap:
        """Resolve controlled joints (default: every actuated joint, actuator order).

        Torque limits: for a motor, ``gear * ctrl_range`` intersected with the force range; for
        other actuator kinds, the force range (a position actuator still cannot push harder).

        Raises:
            UnknownNameError: An unknown joint name.
            ControllerSetupError: A joint with no actuator, a multi-dof joint, a repeated joint,
                or a robot with no actuated joint.
        """
        if joints is None:
            joints = [a.joint for a in robot.actuators.values() if a.joint]
        joints = tuple(joints)
        if not joints:
            raise ControllerSetupError(
                f"{robot.name!r} has no actuated joint to control; actuators: {list(robot.actuators)}"
            )
        if len(set(joints)) != len(joints):
            dup = sorted({j for j in joints if joints.count(j) > 1})
            raise ControllerSetupError(f"controlled joints must be distinct; repeated: {dup}")
        by_joint = {a.joint: a for a in reversed(list(robot.actuators.values())) if a.joint}
        infos, layouts = [], []
        for name in joints:
            layout = robot.joint(name)
            if layout.nv != 1:
                raise ControllerSetupError(
                    f"joint {name!r} is a {layout.kind} joint with {layout.nv} dofs; joint-space "
                    "controllers drive 1-dof (hinge or slide) joints"
                )
            info = by_joint.get(name)
            if info is None:
                raise ControllerSetupError(
                    f"joint {name!r} has no actuator; actuated joints: {list(by_joint)}"
                )
            infos.append(info)
            layouts.append(layout)
        low, high = [], []
        for a in infos:
            lo, hi = a.force_range
            if a.kind == "torque":
                c = sorted((a.gear * a.ctrl_range[0], a.gear * a.ctrl_range[1]))
                lo, hi = max(lo, c[0]), min(hi, c[1])
            low.append(lo)
            high.append(hi)
        index = np.array([a.index for a in infos], dtype=int)
        arrays = [
            np.array([j.idx_q for j in layouts], dtype=int),
            np.array([j.idx_v for j in layouts], dtype=int),
            index,
            np.array(low, dtype=float),
            np.array(high, dtype=float),
        ]
        for arr in arrays:
            arr.setflags(write=False)
        idx_q, idx_v, index, tau_low, tau_high = arrays
        covers = bool(index.size == robot.nu and np.array_equal(index, np.arange(robot.nu)))
        return cls(joints, tuple(a.name for a in infos), idx_q, idx_v, index, covers, tau_low,
                   tau_high)


def _selector(index: np.ndarray) -> slice | np.ndarray:
    if index.size and np.array_equal(index, np.arange(index[0], index[0] + index.size)):
        return slice(int(index[0]), int(index[0]) + int(index.size))
    return np.asarray(index)


class TorqueSaturation:
    """Clips torques to the actuators' limits and counts how often each one saturates.

    Attributes:
        low: Lower limits (n,) [N m].
        high: Upper limits (n,) [N m].
        counts: Cycles in which each joint's torque was clipped (n,).
        saturated_cycles: Cycles in which any joint was clipped.
        cycles: Cycles seen since the last reset.
    """

    def __init__(self, joint_map: JointMap, enabled: bool = True):
        self.joints = joint_map.joints
        self.low = np.asarray(joint_map.tau_low)
        self.high = np.asarray(joint_map.tau_high)
        self.enabled = enabled and bool(np.isfinite(self.low).any() or np.isfinite(self.high).any())
        self.counts = np.zeros(len(self.joints), dtype=int)
        self.saturated_cycles = 0
        self.cycles = 0
        self._small = len(self.joints) <= SMALL_VECTOR_MAX
        self._low_list = self.low.tolist()
        self._high_list = self.high.tolist()
        self._below = np.zeros(len(self.joints), dtype=bool)
        self._above = np.zeros(len(self.joints), dtype=bool)

    def reset(self) -> None:
        """Zero the counters."""
        self.counts[:] = 0
        self.saturated_cycles = 0
        self.cycles = 0

    def apply(self, tau: np.ndarray) -> np.ndarray:
        """Clip ``tau`` (n,) in place to [low, high]; count the clipped joints. Returns ``tau``."""
        self.cycles += 1
        if self.enabled:
            if self._small and not any_outside(
                tau.tolist(), self._low_list, self._high_list
            ):
                return tau  # few joints, none out of range: plain Python is the cheap check
            # two comparisons into preallocated masks and two counts (cheaper than
            # np.clip or ndarray.any on small vectors); clip only when something is out of range
            below = np.less(tau, self.low, out=self._below)
            above = np.greater(tau, self.high, out=self._above)
            if np.count_nonzero(below) or np.count_nonzero(above):
                self.counts += below
                self.counts += above
                self.saturated_cycles += 1
                np.maximum(tau, self.low, out=tau)
                np.minimum(tau, self.high, out=tau)
        return tau

    def by_joint(self) -> dict[str, int]:
        """Clipped cycles per joint name (non-zero only)."""
        return {j: int(c) for j, c in zip(self.joints, self.counts, strict=True) if c}

    def summary(self) -> dict[str, object]:
        """Counts for reports: cycles, saturated cycles, per-joint counts and the limits [N m]."""
        return {
            "cycles": self.cycles,
            "saturated_cycles": self.saturated_cycles,
            "by_joint": self.by_joint(),
            "limits_N_m": {j: [float(lo), float(hi)]
                           for j, lo, hi in zip(self.joints, self.low, self.high, strict=True)},
        }


#: What a controller's output is called in the construction-time check's message.
_OUTPUT_WORDS = {CommandKind.TORQUE: "torques", CommandKind.POSITION: "position targets",
                 CommandKind.VELOCITY: "velocity targets", CommandKind.CTRL: "raw ctrl values"}


class ControllerBase:
    """Plumbing the controllers share: joint map, output clipping, command names, analytic model.

    Subclasses set ``name``, ``reference_type`` and ``command_kind`` (the kind of command their
    ``compute`` returns: torque unless they say otherwise) and implement ``compute``. The
    constructor checks that the controlled joints' actuators take that kind, so a torque law on
    position actuators fails when it is built, not at the first step.

    Raises:
        ControllerSetupError: An actuator of another kind than ``command_kind`` (the message is
            ``mbctl.robots.commands.kind_mismatch``'s, after what the controller outputs).

    Attributes:
        robot: The robot.
        joint_map: Controlled joints and the limits their outputs are clipped to.
        saturation: Clips the outputs to the joint map's limits and counts the clips.
        model: The analytic Pinocchio model (controllers that call ``_use_model``).
        data: Its ``pin.Data``, owned by the controller.
    """

    name: str
    reference_type: type[JointReference] | type[TaskReference] = JointReference
    command_kind: CommandKind = CommandKind.TORQUE
    model: pin.Model
    data: pin.Data

    def __init__(self, robot: Robot, joint_map: JointMap, saturate: bool = True):
        wrong = kind_mismatch(self.command_kind, [robot.actuator(a) for a in joint_map.actuators])
        if wrong is not None:  # here, not at the first step
            what = _OUTPUT_WORDS[self.command_kind]
            raise ControllerSetupError(f"{type(self).__name__} outputs {what}. {wrong}")
        self.robot = robot
        self.joint_map = joint_map
        self.saturation = TorqueSaturation(joint_map, saturate)
        self._names = joint_map.command_names

    @property
    def joints(self) -> tuple[str, ...]:
        """Controlled joint names: the order of joint references and of the command's values."""
        return self.joint_map.joints

    def reset(self) -> None:
        """Zero the saturation (clip) counters."""
        self.saturation.reset()

    def _use_model(self, pin_model: pin.Model | None) -> None:
        """Set ``model`` (default ``robot.pin_model``) and a fresh ``data``.

        Raises:
            ControllerSetupError: A model whose nq or nv differ from the robot's.
        """
        robot = self.robot
        model = pin_model if pin_model is not None else robot.pin_model
        if (model.nq, model.nv) != (robot.nq, robot.nv):
            raise ControllerSetupError(
                f"pin_model has nq={model.nq}, nv={model.nv}; the robot has "
                f"nq={robot.nq}, nv={robot.nv}"
            )
        self.model = model
        self.data = model.createData()

    def _require_every_dof(self, law: str) -> None:
        """Check that the controlled joints are every dof of the robot (a fixed, fully actuated base).

        Raises:
            ControllerSetupError: Some dofs are not controlled joints.
        """
        robot, idx_v = self.robot, self.joint_map.idx_v.tolist()
        if sorted(idx_v) != list(range(robot.nv)):
            missing = sorted(set(range(robot.nv)) - set(idx_v))
            raise ControllerSetupError(
                f"{law} needs every dof actuated and controlled; {robot.name!r} has "
                f"nv={robot.nv} and dofs {missing[:12]} are not controlled joints "
                "(floating base? weld it with mbctl.robots.edits.weld_base)"
            )


#: Up to this many controlled joints (every dof, in order) the feedback runs on Python floats: six
#: numpy calls on tiny vectors cost more than the arithmetic. Measured: 1.0 against 1.5 us at 2
#: joints, 1.3 against 1.9 at 4, crossover near 6 (the G1's 29 stay on numpy: 2.6 against 6.4 us).
SCALAR_FEEDBACK_MAX = 4


class JointFeedbackController(ControllerBase):
    """A controller with per-joint gains and the feedback ``kp e + kd de`` over its joints.

    ``e = q_ref - q`` and ``de = v_ref - v`` on the controlled joints; the gains' units are the
    subclass's (torque per error for PD laws, acceleration per error for computed torque).

    Attributes:
        gains: kp, kd, one pair per controlled joint.
    """

    def __init__(
        self,
        robot: Robot,
        gains: PDGains,
        joints: Sequence[str] | None = None,
        *,
        saturate: bool = True,
    ):
        super().__init__(robot, JointMap.from_robot(robot, joints), saturate)
        jmap = self.joint_map
        self.gains = gains.broadcast(jmap.size)
        self._idx_q = jmap.q_selector
        self._idx_v = jmap.v_selector
        # the joints are q and v in order (fixed base, every dof): no gather needed
        self._identity = bool(np.array_equal(jmap.idx_v, np.arange(robot.nv))
                              and np.array_equal(jmap.idx_q, np.arange(robot.nq)))
        self._kp = np.asarray(self.gains.kp)
        self._kd = np.asarray(self.gains.kd)
        self._out = np.zeros(jmap.size)
        self._ev = np.zeros(jmap.size)
        self._scalar = self._identity and jmap.size <= SCALAR_FEEDBACK_MAX
        self._kp_kd = list(zip(self._kp.tolist(), self._kd.tolist(), strict=True))
        self._zeros = [0.0] * jmap.size

    def feedback(self, state: RobotState, reference: JointReference,
                 feedforward: np.ndarray | None = None) -> np.ndarray:
        """``kp e + kd de`` (+ ``feedforward`` (n,)) (n,), in a buffer the next call may overwrite.

        Raises:
            ReferenceMismatch: (up to ``SCALAR_FEEDBACK_MAX`` joints) a reference or state whose
                length is not the number of joints (larger ones fail numpy's broadcasting).
        """
        if self._scalar:
            ff = self._zeros if feedforward is None else feedforward.tolist()
            q_ref, v_ref = reference.q.tolist(), reference.v.tolist()
            q, v = state.q.tolist(), state.v.tolist()
            if not len(ff) == len(q_ref) == len(q) == len(v_ref) == len(v) == len(self._zeros):
                raise ReferenceMismatch(
                    f"{type(self).__name__} controls {len(self._zeros)} joints {list(self.joints)}; got "
                    f"a reference q, v of {len(q_ref)}, {len(v_ref)} entries (feed-forward {len(ff)}) "
                    f"and a state q, v of {len(q)}, {len(v)}"
                )
            # lengths checked above: zip's own check (strict=True) costs as much as the arithmetic
            return np.array([f + kp * (a - b) + kd * (c - d) for f, (kp, kd), a, b, c, d in zip(
                ff, self._kp_kd, q_ref, q, v_ref, v, strict=False)])
        out, ev = self._out, self._ev
        if self._identity:
            np.subtract(reference.q, state.q, out=out)
            np.subtract(reference.v, state.v, out=ev)
        else:
            np.subtract(reference.q, state.q[self._idx_q], out=out)
            np.subtract(reference.v, state.v[self._idx_v], out=ev)
        out *= self._kp
        ev *= self._kd
        out += ev
        if feedforward is not None:
            out += feedforward
        return out
