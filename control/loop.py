"""The control loop: read state, compute, send, sync — against any RobotInterface.

``run`` works the same on the simulator and on a robot over DDS, because it only uses the
:class:`~mbctl.robots.interface.RobotInterface` protocol. Every buffer (logs, the pre-sampled
reference) is allocated before the first cycle; a cycle allocates only what the controller and
the interface allocate themselves.

Timing: cycle k reads the state at ``t_k = t_0 + k T`` (T the control period), takes the
reference at ``t_k - t_0``, sends the command, and ``sync()`` holds it for one period.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mbctl.control.controller import Controller, JointReference, TaskReference
from mbctl.control.exceptions import ControlError, ReferenceMismatch
from mbctl.planners.trajectory import JointTrajectory
from mbctl.robots.commands import Command
from mbctl.robots.interface import RobotInterface, RobotState

Reference = JointReference | TaskReference
ReferenceFn = Callable[[float], Reference]
OnStep = Callable[[int, RobotState, Any, Command], "bool | None"]


@dataclass(frozen=True)
class RunLog:
    """What one run measured, one row per control cycle (state before the command).

    Attributes:
        t_s: Cycle times (N,) [s] since the interface's clock started.
        q: Measured configurations (N, nq), Pinocchio convention.
        v: Measured velocities (N, nv).
        command: Command values sent (N, m) ([N m] for torques, [rad] for position targets).
        reference: Reference positions (N, k): joint q_ref [rad] or task p_ref [m].
        reference_v: Reference velocities (N, k).
        wall_time_s: Wall-clock time of the loop [s].
        tick: The plant's tick of each cycle's state (N,) (``RobotState.tick``: aligns the run
            with the plant's own logs, e.g. a bridge's truth log).
    """

    t_s: np.ndarray
    q: np.ndarray
    v: np.ndarray
    command: np.ndarray
    reference: np.ndarray
    reference_v: np.ndarray
    wall_time_s: float
    tick: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.int64))

    @property
    def cycles(self) -> int:
        """Number of control cycles."""
        return int(self.t_s.size)


def presample(
    trajectory: JointTrajectory,
    times_s: np.ndarray,
    joints: Sequence[str],
    hold_q: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sample a trajectory at ``times_s`` into (N, n) arrays ordered by ``joints``.

    Joints the trajectory does not cover hold ``hold_q`` (their entry, by joint order) at zero
    velocity and acceleration.

    Args:
        trajectory: The joint trajectory (its own column names).
        times_s: Sample times (N,) [s] from the trajectory's start.
        joints: The controller's joint order (n,).
        hold_q: Positions (n,) [rad] for joints missing from the trajectory.

    Returns:
        q (N, n) [rad], v (N, n) [rad/s], a (N, n) [rad/s^2].

    Raises:
        ReferenceMismatch: A trajectory joint the controller does not control, or missing joints
            without ``hold_q``.
    """
    joints = list(joints)
    extra = [n for n in trajectory.names if n not in joints]
    if extra:
        raise ReferenceMismatch(
            f"trajectory joints {extra} are not controlled; the controller drives {joints}"
        )
    missing = [j for j in joints if j not in trajectory.names]
    if missing and hold_q is None:
        raise ReferenceMismatch(
            f"trajectory lacks joints {missing}; pass hold_q to hold them (controller joints "
            f"{joints})"
        )
    n_samples, n = len(times_s), len(joints)
    q = np.empty((n_samples, n))
    v = np.zeros((n_samples, n))
    a = np.zeros((n_samples, n))
    if missing:
        q[:] = np.asarray(hold_q, dtype=float)
    cols = np.array([joints.index(name) for name in trajectory.names], dtype=int)
    # vectorised linear interpolation, the same as JointTrajectory.sample, end state held
    t = trajectory.t_s
    tt = np.clip(np.asarray(times_s, dtype=float), t[0], t[-1])
    if len(t) == 1:
        q[:, cols] = trajectory.q[0]
        return q, v, a
    i = np.clip(np.searchsorted(t, tt, side="right") - 1, 0, len(t) - 2)
    w = ((tt - t[i]) / (t[i + 1] - t[i]))[:, None]
    q[:, cols] = (1 - w) * trajectory.q[i] + w * trajectory.q[i + 1]
    after = np.asarray(times_s) >= t[-1]
    v[:, cols] = np.where(after[:, None], 0.0, (1 - w) * trajectory.v[i] + w * trajectory.v[i + 1])
    a[:, cols] = np.where(after[:, None], 0.0, (1 - w) * trajectory.a[i] + w * trajectory.a[i + 1])
    return q, v, a


def run(
    interface: RobotInterface,
    controller: Controller[Any],
    reference: JointTrajectory | ReferenceFn | Reference | None,
    duration_s: float,
    on_step: OnStep | None = None,
    *,
    hold_q: np.ndarray | None = None,
) -> RunLog:
    """Run ``controller`` on ``interface`` for ``duration_s`` and log every cycle.

    However the loop ends (done, the callback, an exception, Ctrl-C), it calls ``interface.stop()``:
    the plant keeps the robot safe from then on (over DDS, the damping command every period) while
    the caller writes its results, until it closes the plant.

    Args:
        interface: Any RobotInterface (the simulator, or a robot over DDS).
        controller: The control law; ``reset()`` is called first.
        reference: A JointTrajectory (pre-sampled at the control times, columns matched to
            ``controller.joints`` by name), a function of time since start ``t [s] -> reference``,
            a constant JointReference / TaskReference, or None for a controller that carries its
            own targets (``reference_type = None``, e.g. a scheduled whole-body controller).
        duration_s: How long to run [s]; rounded to whole control periods (at least one).
        on_step: Called after each cycle as ``on_step(k, state, reference, command)``, once the
            interface has run the command for the period (``sync``): ``state`` is the one the
            command was computed from, and the plant's measurements of the period (contact forces)
            are available (e.g. to stream a row: the run keeps every completed cycle even if
            interrupted). A true return value ends the run after that cycle (e.g. the robot
            fell); the log then holds the cycles run.
        hold_q: For a trajectory that covers only some of the controller's joints: positions
            (n,) [rad] the others hold.

    Returns:
        The RunLog.

    Raises:
        ControlError: A non-positive or non-finite duration.
        ReferenceMismatch: A trajectory that does not fit the controller's joints, or a
            reference of another type than the controller's ``reference_type`` (if it has one).
        ToolkitError: Whatever the interface raises (bad command kind, divergence).
    """
    if not np.isfinite(duration_s) or duration_s <= 0:
        raise ControlError(f"duration_s must be finite and > 0; got {duration_s}")
    period = interface.control_period_s
    n_cycles = max(1, int(round(duration_s / period)))
    t_rel = np.arange(n_cycles) * period
    robot = interface.robot
    fn: ReferenceFn | None = None
    sampled: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
    constant: Reference | None = None
    no_reference = reference is None
    if no_reference:
        if getattr(controller, "reference_type", JointReference) is not None:
            raise ReferenceMismatch(
                f"{type(controller).__name__} takes a reference; pass a JointTrajectory, a function "
                "of time or a constant reference (None is for controllers that carry their targets)"
            )
    elif isinstance(reference, JointTrajectory):
        joints = getattr(controller, "joints", None) or reference.names
        sampled = presample(reference, t_rel, joints, hold_q)
    elif isinstance(reference, (JointReference, TaskReference)):
        constant = reference
    elif callable(reference):
        fn = reference
    else:
        raise ReferenceMismatch(
            "reference must be a JointTrajectory, a function of time, or a JointReference / "
            f"TaskReference; got {type(reference).__name__}"
        )
    refs: list[JointReference] | None = None
    if sampled is not None:
        for arr in sampled:
            arr.setflags(write=False)
        ref_q, ref_v, ref_a = sampled
        refs = list(map(JointReference._make, zip(ref_q, ref_v, ref_a, strict=True)))  # row views
    first: Reference | None
    if no_reference:
        first = None
    elif constant is not None:
        first = constant
    elif fn is not None:
        first = fn(0.0)
    else:
        first = refs[0]  # type: ignore[index]  # one of the three branches above set it
    expected = getattr(controller, "reference_type", None)
    if expected is not None and not isinstance(first, expected):
        raise ReferenceMismatch(
            f"{type(controller).__name__} takes a {expected.__name__}; the reference gives a "
            f"{type(first).__name__}"
        )
    k_ref = 0 if first is None else np.size(first[0])
    log_t = np.empty(n_cycles)
    log_tick = np.empty(n_cycles, dtype=np.int64)
    log_q = np.empty((n_cycles, robot.nq))
    log_v = np.empty((n_cycles, robot.nv))
    log_ref = np.empty((n_cycles, k_ref) if sampled is None else (0, k_ref))
    log_ref_v = np.empty((n_cycles, k_ref) if sampled is None else (0, k_ref))
    log_cmd = np.empty((n_cycles, 0))  # resized on the first command (its width is the controller's)
    controller.reset()
    t0 = interface.time_s
    # bound methods looked up once: the loop body is the hot path
    read_state, compute = interface.read_state, controller.compute
    send, sync = interface.send, interface.sync
    log_refs = refs is None and not no_reference
    wall0 = time.perf_counter()
    try:
        for k in range(n_cycles):
            state = read_state()
            if refs is not None:
                ref: Reference = refs[k]
            elif fn is not None:
                ref = fn(state.time_s - t0)
            else:
                ref = constant  # type: ignore[assignment]
            command = compute(state, ref)
            send(command)
            sync()
            if k == 0:
                log_cmd = np.empty((n_cycles, command.values.size))
            log_t[k] = state.time_s
            log_tick[k] = state.tick
            log_q[k] = state.q
            log_v[k] = state.v
            log_cmd[k] = command.values
            if log_refs:
                log_ref[k] = ref[0]
                log_ref_v[k] = ref[1]
            if on_step is not None and on_step(k, state, ref, command):
                n_run = k + 1  # the callback ended the run (e.g. the robot fell)
                break
        else:
            n_run = n_cycles
    finally:  # however the loop ends, the plant keeps the robot safe from now on (the contract)
        interface.stop()
    wall = time.perf_counter() - wall0
    if sampled is not None:  # a pre-sampled trajectory is its own log
        log_ref, log_ref_v = sampled[0], sampled[1]
    if n_run < n_cycles:
        log_t, log_q, log_v, log_cmd = log_t[:n_run], log_q[:n_run], log_v[:n_run], log_cmd[:n_run]
        log_tick = log_tick[:n_run]
        log_ref, log_ref_v = log_ref[:n_run], log_ref_v[:n_run]
    return RunLog(log_t, log_q, log_v, log_cmd, log_ref, log_ref_v, wall, log_tick)
