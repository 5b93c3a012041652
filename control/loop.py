"""The control loop: read state, compute, send, sync — against any RobotInterface.

``run`` works the same on the simulator and on a robot over DDS, because it only uses the
:class:`~mbctl.robots.interface.RobotInterface` protocol. Every buffer (logs, the reference's
samples, the figures' sums) is allocated before the first cycle; a cycle allocates only what the
controller and the interface allocate themselves.

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

#: Rows of q, v, command and reference a RunLog keeps at most (the G1: about 1.3 kB a row, 0.13 GB):
#: a longer run keeps every ``stride``-th cycle and its last (the same bound as the replay's samples,
#: ``mbctl.sim.recorder.MAX_REPLAY_SAMPLES``). Its times, ticks and :class:`RunStats` cover every cycle.
MAX_LOG_ROWS = 100_000
#: Cycles of a JointTrajectory reference sampled at once (the G1: about 7 MB of q, v, a).
SAMPLE_CHUNK = 10_000
#: Cycles staged before :class:`RunStats` takes their sums (vectorised, off the per-cycle path).
STATS_BLOCK = 512


@dataclass(frozen=True)
class ColumnStats:
    """Per-column extremes and sums of a quantity over every cycle of a run.

    Attributes:
        count: Cycles summed.
        min: Smallest value of each column (n,).
        max: Largest value of each column (n,).
        sum: Sum of each column (n,).
        sum_sq: Sum of the squares of each column (n,).
    """

    count: int
    min: np.ndarray
    max: np.ndarray
    sum: np.ndarray
    sum_sq: np.ndarray

    def max_abs(self, center: np.ndarray | float = 0.0) -> np.ndarray:
        """Largest ``|x - center|`` of each column (n,) (``center`` (n,) or a scalar)."""
        return np.maximum(self.max - center, center - self.min)

    def rms(self) -> np.ndarray:
        """Root mean square of each column (n,)."""
        return np.sqrt(self.sum_sq / self.count)

    def rms_all(self) -> float:
        """Root mean square over every entry of every cycle."""
        return float(np.sqrt(self.sum_sq.sum() / (self.count * self.sum_sq.size)))


@dataclass(frozen=True)
class RunStats:
    """Exact figures of every cycle of a run, whatever rows its log kept.

    Attributes:
        q: Measured configurations (nq columns).
        v: Measured velocities (nv columns).
        command: Command values sent (m columns).
        error: Joint tracking error ``q_ref - q`` [rad] in the controller's joint order, for a
            JointReference and a controller with a ``joint_map``; else None.
    """

    q: ColumnStats
    v: ColumnStats
    command: ColumnStats
    error: ColumnStats | None


@dataclass(frozen=True)
class RunLog:
    """What one run measured (the state before each cycle's command).

    The times and ticks cover every cycle. The rows (q, v, command, reference) are every cycle of
    a run of at most ``MAX_LOG_ROWS`` cycles (``stride`` 1); a longer one keeps every
    ``stride``-th cycle and the last, ``cycle`` naming each row's cycle. Figures over the whole run
    come from ``stats``, which sums every cycle.

    Attributes:
        t_s: Every cycle's time (N,) [s] since the interface's clock started.
        q: Measured configurations (R, nq), Pinocchio convention.
        v: Measured velocities (R, nv).
        command: Command values sent (R, m) ([N m] for torques, [rad] for position targets).
        reference: Reference positions (R, k): joint q_ref [rad] or task p_ref [m].
        reference_v: Reference velocities (R, k).
        wall_time_s: Wall-clock time of the loop [s].
        tick: The plant's tick of every cycle's state (N,) (``RobotState.tick``: aligns the run
            with the plant's own logs, e.g. a bridge's truth log).
        cycle: The cycle of each row (R,) (empty: every cycle, rows = cycles).
        stride: Cycles between kept rows (1: every cycle kept).
        stats: Sums over every cycle (None for a log made by hand).
    """

    t_s: np.ndarray
    q: np.ndarray
    v: np.ndarray
    command: np.ndarray
    reference: np.ndarray
    reference_v: np.ndarray
    wall_time_s: float
    tick: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.int64))
    cycle: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.int64))
    stride: int = 1
    stats: RunStats | None = None

    def __post_init__(self) -> None:
        if self.cycle.size == 0 and len(self.q):
            object.__setattr__(self, "cycle", np.arange(len(self.q)))

    @property
    def cycles(self) -> int:
        """Number of control cycles run."""
        return int(self.t_s.size)

    @property
    def rows(self) -> int:
        """Number of rows kept."""
        return int(len(self.q))

    @property
    def row_time_s(self) -> np.ndarray:
        """Each row's time (R,) [s]."""
        return self.t_s[self.cycle]

    @property
    def row_tick(self) -> np.ndarray:
        """Each row's tick (R,)."""
        return self.tick[self.cycle]

    def sums(self) -> RunStats:
        """The sums over every cycle.

        Raises:
            ControlError: A log made by hand (no sums).
        """
        if self.stats is None:
            raise ControlError("this RunLog has no sums over its cycles (a log made by hand, not by run())")
        return self.stats

    def error_sums(self) -> ColumnStats:
        """The joint tracking error's sums over every cycle.

        Raises:
            ControlError: No error summed (the loop sums it for a joint reference and a controller
                with a joint map).
        """
        error = self.sums().error
        if error is None:
            raise ControlError("the control loop summed no joint tracking error (a joint reference and a "
                               "controller with a joint map are needed)")
        return error


def log_stride(n_cycles: int, max_rows: int) -> int:
    """Cycles between kept rows so that every ``stride``-th cycle and the last fit ``max_rows``.

    Args:
        n_cycles: Cycles of the run.
        max_rows: Rows at most (>= 2).
    """
    if max_rows < 2:
        raise ControlError(f"max_rows must be >= 2 (the first and the last cycle); got {max_rows}")
    return max(1, -(-(n_cycles - 1) // (max_rows - 1)))


def log_rows(n_cycles: int, stride: int) -> int:
    """Rows a log of ``n_cycles`` keeps at ``stride``: cycles 0, stride, 2 stride, ... and the last."""
    return len(kept_cycles(n_cycles, stride)) if n_cycles > 0 else 0


def kept_cycles(n_cycles: int, stride: int) -> np.ndarray:
    """The cycles a log of ``n_cycles`` keeps at ``stride`` (0, stride, 2 stride, ... and the last)."""
    cycles = np.arange(0, n_cycles, stride)
    return np.append(cycles, n_cycles - 1) if n_cycles and (n_cycles - 1) % stride else cycles


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


class _Sums:
    """Stages each cycle's q, v, command (and joint error) and folds them into per-column sums."""

    def __init__(self, nq: int, nv: int, m: int, idx_q: np.ndarray | None):
        self.cols = np.cumsum([0, nq, nv, m, 0 if idx_q is None else idx_q.size])
        self.idx_q = idx_q
        width = int(self.cols[-1])
        self.block = np.empty((STATS_BLOCK, width))
        self.n = 0
        self.count = 0
        self.min = np.full(width, np.inf)
        self.max = np.full(width, -np.inf)
        self.sum = np.zeros(width)
        self.sum_sq = np.zeros(width)
        c = self.cols
        self.q_, self.v_, self.cmd_, self.err_ = (slice(int(c[i]), int(c[i + 1])) for i in range(4))

    def fold(self) -> None:
        """Add the staged cycles to the sums."""
        b = self.block[: self.n]
        if self.idx_q is not None:  # the reference staged in the error's columns: q_ref - q
            b[:, self.err_] -= b[:, self.q_][:, self.idx_q]
        np.minimum(self.min, b.min(axis=0), out=self.min)
        np.maximum(self.max, b.max(axis=0), out=self.max)
        self.sum += b.sum(axis=0)
        self.sum_sq += np.einsum("ij,ij->j", b, b)
        self.count += self.n
        self.n = 0

    def stats(self) -> RunStats:
        """The sums so far."""
        self.fold()

        def part(s: slice) -> ColumnStats:
            return ColumnStats(self.count, self.min[s].copy(), self.max[s].copy(), self.sum[s].copy(),
                               self.sum_sq[s].copy())

        return RunStats(part(self.q_), part(self.v_), part(self.cmd_),
                        None if self.idx_q is None else part(self.err_))


def run(
    interface: RobotInterface,
    controller: Controller[Any],
    reference: JointTrajectory | ReferenceFn | Reference | None,
    duration_s: float,
    on_step: OnStep | None = None,
    *,
    hold_q: np.ndarray | None = None,
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
    stride = log_stride(n_cycles, MAX_LOG_ROWS)
    n_rows = log_rows(n_cycles, stride)
    log_t = np.empty(n_cycles)
    log_tick = np.empty(n_cycles, dtype=np.int64)
    log_cycle = np.empty(n_rows, dtype=np.int64)
    log_q = np.empty((n_rows, robot.nq))
    log_v = np.empty((n_rows, robot.nv))
    log_ref = np.empty((n_rows, k_ref))
    log_ref_v = np.empty((n_rows, k_ref))
    log_cmd = np.empty((n_rows, 0))  # resized on the first command (its width is the controller's)
    sums: _Sums | None = None
    controller.reset()
    t0 = interface.time_s
    # bound methods looked up once: the loop body is the hot path
    read_state, compute = interface.read_state, controller.compute
    send, sync = interface.send, interface.sync
    refs = sampler.refs if sampler is not None else None
    chunk0 = 0
    log_refs = not no_reference
    row = 0  # the row this cycle goes to: kept when k % stride == 0, else until the next kept cycle
    n_run = 0
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
            if k == 0:
                log_cmd = np.empty((n_rows, command.values.size))
                sums = _Sums(robot.nq, robot.nv, command.values.size, idx_q)
                block, s_q, s_v, s_cmd, s_err = sums.block, sums.q_, sums.v_, sums.cmd_, sums.err_
            log_t[k] = state.time_s
            log_tick[k] = state.tick
            log_cycle[row] = k
            log_q[row] = state.q
            log_v[row] = state.v
            log_cmd[row] = command.values
            if log_refs:
                log_ref[row] = ref[0]
                log_ref_v[row] = ref[1]
            b = block[sums.n]  # type: ignore[union-attr]
            b[s_q] = state.q
            b[s_v] = state.v
            b[s_cmd] = command.values
            if idx_q is not None:
                b[s_err] = ref[0]
            sums.n += 1  # type: ignore[union-attr]
            if sums.n == STATS_BLOCK:  # type: ignore[union-attr]
                sums.fold()  # type: ignore[union-attr]
            if k % stride == 0:
                row += 1
            n_run = k + 1
            if on_step is not None and on_step(k, state, ref, command):
                break  # the callback ended the run (e.g. the robot fell)
    finally:  # however the loop ends, the plant keeps the robot safe from now on (the contract)
        interface.stop()
    wall = time.perf_counter() - wall0
    kept = log_rows(n_run, stride)  # the last cycle run is kept too, when not a stride's
    return RunLog(log_t[:n_run], log_q[:kept], log_v[:kept], log_cmd[:kept], log_ref[:kept],
                  log_ref_v[:kept], wall, log_tick[:n_run], log_cycle[:kept], stride,
                  sums.stats() if sums is not None else None)
