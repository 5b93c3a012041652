"""The control loop: read state, compute, send, sync — against any RobotInterface.

``run`` works the same on the simulator and on a robot over DDS, because it only uses the
:class:`~mbctl.robots.interface.RobotInterface` protocol. The log's arrays are allocated before
the first cycle; each cycle's state, reference and command are copied into small staging arrays and
written into them :data:`~mbctl.control.run_log.LOG_BATCH` cycles at a time
(:class:`~mbctl.control.run_log.LogWriter`).

Memory is bounded: the log keeps at most ``MAX_LOG_ROWS`` rows of q, v, command and reference
(every ``stride``-th cycle and the last of a longer run), its times and ticks every cycle (16 bytes
a cycle), and :class:`RunStats` sums every cycle, so a figure over the whole run (an RMS, a largest
deviation) stays exact however long the run. A JointTrajectory reference is sampled
:data:`SAMPLE_CHUNK` cycles at a time.

Timing: cycle k reads the state at ``t_k = t_0 + k T`` (T the control period), takes the
reference at ``t_k - t_0``, sends the command, and ``sync()`` holds it for one period.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from mbctl.control.controller import Controller, JointReference, TaskReference
from mbctl.control.exceptions import ControlError, ReferenceMismatch

# the log's types, where the loop's callers have always found them
from mbctl.control.run_log import (  # noqa: F401
    LOG_BATCH,
    MAX_LOG_ROWS,
    ColumnStats,
    LogWriter,
    RunLog,
    RunStats,
    batch_rows,
    kept_cycles,
    log_rows,
    log_stride,
)
from mbctl.planners.trajectory import JointTrajectory
from mbctl.robots.commands import Command
from mbctl.robots.interface import RobotInterface, RobotState

Reference = JointReference | TaskReference
ReferenceFn = Callable[[float], Reference]
OnStep = Callable[[int, RobotState, Any, Command], "bool | None"]

#: Cycles of a JointTrajectory reference sampled at once (the G1: about 7 MB of q, v, a).
SAMPLE_CHUNK = 10_000


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


class _Sampler:
    """A JointTrajectory's references, sampled :data:`SAMPLE_CHUNK` cycles at a time (read-only rows)."""

    def __init__(self, trajectory: JointTrajectory, joints: Sequence[str], hold_q: np.ndarray | None,
                 period_s: float, n_cycles: int):
        self.trajectory, self.joints, self.hold_q = trajectory, list(joints), hold_q
        self.period_s, self.n_cycles = period_s, n_cycles
        self.start = -1
        self.refs: list[JointReference] = []
        self.chunk(0)

    def chunk(self, k: int) -> list[JointReference]:
        """Sample the chunk starting at cycle ``k``; its references, one per cycle."""
        end = min(k + SAMPLE_CHUNK, self.n_cycles)
        sampled = presample(self.trajectory, np.arange(k, end) * self.period_s, self.joints, self.hold_q)
        for arr in sampled:
            arr.setflags(write=False)
        self.start = k
        self.refs = list(map(JointReference._make, zip(*sampled, strict=True)))  # row views
        return self.refs


def run(
    interface: RobotInterface,
    controller: Controller[Any],
    reference: JointTrajectory | ReferenceFn | Reference | None,
    duration_s: float,
    on_step: OnStep | None = None,
    *,
    hold_q: np.ndarray | None = None,
    log_batch: int = LOG_BATCH,
    rows: bool = True,
) -> RunLog:
    """Run ``controller`` on ``interface`` for ``duration_s`` and log it (see :class:`RunLog`).

    However the loop ends (done, the callback, an exception, Ctrl-C), it calls ``interface.stop()``:
    the plant keeps the robot safe from then on (over DDS, the damping command every period) while
    the caller writes its results, until it closes the plant.

    Args:
        interface: Any RobotInterface (the simulator, or a robot over DDS).
        controller: The control law; ``reset()`` is called first.
        reference: A JointTrajectory (sampled at the control times, columns matched to
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
        log_batch: Cycles the log keeps before it writes them (one stall of the loop each time; a
            plant without deadlines, in-process, can take larger batches at a lower cost a cycle).
        rows: False: the log keeps every cycle's time and tick only, no rows of q, v, command and
            reference and no sums (for a caller that records what it needs itself in ``on_step``;
            about 2.5 us less a cycle of a 29-joint humanoid).

    Returns:
        The RunLog: at most ``MAX_LOG_ROWS`` rows, times, ticks and stats of every cycle.

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
    robot = interface.robot
    fn: ReferenceFn | None = None
    sampler: _Sampler | None = None
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
        sampler = _Sampler(reference, joints, hold_q, period, n_cycles)
    elif isinstance(reference, (JointReference, TaskReference)):
        constant = reference
    elif callable(reference):
        fn = reference
    else:
        raise ReferenceMismatch(
            "reference must be a JointTrajectory, a function of time, or a JointReference / "
            f"TaskReference; got {type(reference).__name__}"
        )
    first: Reference | None
    if no_reference:
        first = None
    elif constant is not None:
        first = constant
    elif fn is not None:
        first = fn(0.0)
    else:
        first = sampler.refs[0]  # type: ignore[union-attr]  # one of the branches above set it
    expected = getattr(controller, "reference_type", None)
    if expected is not None and not isinstance(first, expected):
        raise ReferenceMismatch(
            f"{type(controller).__name__} takes a {expected.__name__}; the reference gives a "
            f"{type(first).__name__}"
        )
    k_ref = 0 if first is None else np.size(first[0])
    joint_map = getattr(controller, "joint_map", None)
    idx_q = (np.asarray(joint_map.idx_q, dtype=int)
             if isinstance(first, JointReference) and joint_map is not None
             and np.size(joint_map.idx_q) == k_ref else None)
    log = LogWriter(n_cycles, robot.nq, robot.nv, k_ref, idx_q, MAX_LOG_ROWS, log_batch, rows)
    keep = log.keep if rows else log.keep_times
    controller.reset()
    t0 = interface.time_s
    # bound methods looked up once: the loop body is the hot path
    read_state, compute = interface.read_state, controller.compute
    send, sync = interface.send, interface.sync
    refs = sampler.refs if sampler is not None else None
    chunk0 = 0
    wall0 = time.perf_counter()
    try:
        for k in range(n_cycles):
            state = read_state()
            if refs is not None:
                if k - chunk0 == SAMPLE_CHUNK:
                    refs, chunk0 = sampler.chunk(k), k  # type: ignore[union-attr]
                ref: Reference = refs[k - chunk0]
            elif fn is not None:
                ref = fn(state.time_s - t0)
            else:
                ref = constant  # type: ignore[assignment]
            command = compute(state, ref)
            send(command)
            sync()
            keep(state, ref, command)  # copied as it is staged: a function's buffers may be reused
            if on_step is not None and on_step(k, state, ref, command):
                break  # the callback ended the run (e.g. the robot fell)
    finally:  # however the loop ends, the plant keeps the robot safe from now on (the contract)
        interface.stop()
    wall = time.perf_counter() - wall0
    log.write()
    return log.log(wall)
