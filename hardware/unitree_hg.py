"""A Unitree ``unitree_hg`` robot (the G1 by default) over its low-level DDS, as a robot interface.

It implements :class:`~mbctl.robots.interface.RobotInterface`, the plant contract.

The interface is generic over the robots that speak ``unitree_hg``: a robot is its model and its
:class:`~mbctl.unitree.tables.MotorTable` (data: the G1's 29- and 23-motor tables ship;
:data:`UnitreeG1` is this class, named for the robot it is used with most).

The same controller object that runs on the simulator runs here, through ``control.loop.run``:
``read_state`` takes the latest ``rt/lowstate`` (LowState_), ``send`` fills a LowCmd_ and
publishes it on ``rt/lowcmd``, ``sync`` waits for the robot's next state (the robot's state
stream is the wall clock; GIL released while waiting) and watches the link.

Lifecycle (as ros2_control's hardware components, and the plant contract of
:class:`~mbctl.robots.interface.RobotInterface`): constructing the interface configures DDS;
``open()`` (called by the constructor unless ``activate=False``) *activates* it only once the
robot's state stream has been read: :data:`~mbctl.hardware.lowstate.RATE_STATES` valid states
within ``connect_timeout_s`` (their arrivals measure the state rate, which paces the loop and
scales the watchdog, unless ``rate_hz`` is given), else :class:`NoRobotError` saying what was seen
(nothing on the domain, states with a bad CRC, states that never advance); a joint outside its
limits raises :class:`JointOutOfLimits` naming it; another ``rt/lowcmd`` writer (a second client)
raises :class:`~mbctl.unitree.exceptions.AnotherWriterError` (:mod:`~mbctl.hardware.command_link`);
nothing is commanded in any case.
``stop()`` ends the loop's commanding: the damping command goes out every period from a thread
(:class:`~mbctl.hardware.damping.DampingKeeper`) until ``close()``, or until a new command
resumes (another loop). ``close()`` deactivates: it sends the damping command (``kp = 0``, ``kd``
per motor) if anything was commanded, then leaves DDS. Use it as a context manager.

Messages: every LowCmd_ carries ``mode_pr`` = 0 (pitch/roll ankles), the ``mode_machine`` of the
first LowState, each motor's mode (enabled), q, dq, tau, kp, kd, and the CRC. LowStates are checked,
ordered and timed by :class:`~mbctl.hardware.lowstate.LowStateStream`.

State: joint q and dq come from the motors; the base orientation and angular velocity from the
IMU; the base position and linear velocity are not measured, so they come from the estimator the
job gives (:class:`~mbctl.robots.interface.BaseStateEstimator`) and ``RobotState.estimated`` says so.

Safety: ``watchdog_periods`` periods without a new LowState send the damping command and raise
:class:`LinkLost` ("link lost", with what the stream saw); the watchdog arms after the first
completed cycle (the first waits up to ``FIRST_CYCLE_S``, 1 s from its start, however long
connecting took: a plant that only starts on the first command, a first cycle that warms up);
commands are clamped to the model's torque and position limits and counted; Ctrl-C
(KeyboardInterrupt) goes through ``close()`` and so damps; ``dry_run`` reads and never commands.

Stalls (``quiet_loop``; measured in bench/bench_dds.py, see docs/api/dds.rst): the loop's first
``read_state`` freezes every object made before it (``gc.freeze``; ``close()`` undoes it), turns
collection off until ``stop()`` and raises the loop to real-time priority where the OS permits
(:class:`~mbctl.unitree.clock.RealtimePriority`; the report's ``realtime``). Waits happen in C with
the GIL released; no reader thread (the loop takes the states).
"""

from __future__ import annotations

import gc
import time
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from mbctl.hardware.command_link import check_command_link
from mbctl.hardware.damping import DampingKeeper
from mbctl.hardware.dds_options import DdsOptions
from mbctl.hardware.exceptions import DryRunError, HardwareError, JointOutOfLimits, LinkLost, NoRobotError
from mbctl.hardware.lowstate import PERIOD_RANGE_S, RATE_STATES, LowStateStream
from mbctl.hardware.motor_commands import MotorCommandWriter, MotorGains, default_damping, write_damping
from mbctl.hardware.motor_law import stabilize
from mbctl.robots.commands import Command
from mbctl.robots.interface import BaseStateEstimator, Proprioception, RobotState
from mbctl.robots.model_pair import Robot
from mbctl.robots.plant_report import LinkReport, PlantReport, SafetyReport, TimingReport
from mbctl.unitree import TOPIC_LOWCMD, TOPIC_LOWSTATE, Channel
from mbctl.unitree.channel import RawWriter, message_types
from mbctl.unitree.clock import CycleClock, RealtimePriority
from mbctl.unitree.motors import MODE_PR, MOTOR_ENABLED, MotorMap
from mbctl.unitree.tables import G1_29DOF, MotorTable
from mbctl.unitree.wire import low_cmd_codec

#: The longest the first cycle waits for the robot's answer [s], from its own start (the watchdog
#: arms after it).
FIRST_CYCLE_S = 1.0


class UnitreeHG:
    """A ``unitree_hg`` robot over Unitree's low-level DDS (see the module docstring).

    Args:
        robot: The robot's model pair (its joint names are the table's; any actuator kinds).
        estimator: Estimates the base position and linear velocity.
        options: Domain, network interface, timing and safety options.
        table: The robot's motor table (default: the 29-dof G1's).
        activate: Connect now (``open()``); False leaves it to the caller.
        gains: Gains of position and velocity targets (default: the model's position actuators').
        damping_kd: Damping [N m s/rad] per motor for the damping command (default: the torque
            limit reached at 10 rad/s).
        feet: Frames on the ground at connect (a robot standing there), for the stability of the
            gains (``DdsOptions.stable_gains``); none: judged with the robot in the air.

    Raises:
        ChannelError: The hardware extra is missing, a bad domain or an unknown interface.
        NoRobotError: No state stream within ``connect_timeout_s``.
        AnotherWriterError: Another ``rt/lowcmd`` writer on the domain (not in a dry run).
        JointOutOfLimits: A joint outside its limits at start.
        MotorTableError: A robot that does not match ``table``.
    """

    def __init__(
        self,
        robot: Robot,
        estimator: BaseStateEstimator,
        options: DdsOptions | None = None,
        *,
        table: MotorTable = G1_29DOF,
        activate: bool = True,
        gains: MotorGains | None = None,
        damping_kd: npt.ArrayLike | None = None,
        feet: Sequence[str] = (),
    ):
        self.options = options or DdsOptions()
        self._robot = robot
        self.table = table
        self.motors = MotorMap.for_robot(robot, table)
        self.estimator = estimator
        self.feet = tuple(feet)
        self.gains = gains or MotorGains.from_actuators(robot, self.motors)
        self.damping_kd = (default_damping(self.motors) if damping_kd is None
                           else np.asarray(damping_kd, dtype=float))
        self.commands = MotorCommandWriter(robot, self.motors, self.gains)
        #: Gains lowered at connect for stability (``stable_gains``): joint -> {gain: (given, sent)}.
        self.gains_lowered: dict[str, dict[str, tuple[float, float]]] = {}
        self._cmd_codec = low_cmd_codec()
        self._motor_cmd = self._cmd_codec.message["motor_cmd"]  # (a view of the codec's buffer, once)
        self._period = 1.0 / self.options.rate_hz if self.options.rate_hz else 0.002
        self._clock = CycleClock(self._period)
        self.stale = self.watchdog_events = 0
        #: The LowState tick of the state each cycle used, the last ``read_state`` before its
        #: ``sync`` (aligns a run's cycles with the bridge's truth log, one entry per cycle).
        self.state_ticks: list[int] = []
        self._read_this_cycle = False
        self._commanded = False
        self._froze_gc = False
        self._gc_was_on = False
        self._realtime = RealtimePriority()
        self._ran_realtime = False
        self._armed = False
        self._loop_start = -float("inf")  # when cycle 0 began (time.perf_counter) [s]
        self._fresh = False
        self._state: RobotState | None = None
        self._damped = False
        self._active = False
        self._keeper: DampingKeeper | None = None
        self.mode_machine: int | None = None
        lowcmd, lowstate = message_types()
        o = self.options
        self.channel = Channel(o.domain, o.network_interface, o.cyclone_config)
        try:
            self._t0 = time.perf_counter()
            self._lowcmd_writers = self.channel.writers(TOPIC_LOWCMD, lowcmd)
            # a dry run never commands: no writer (another client beside it is no conflict)
            self._writer = None if o.dry_run else self.channel.writer(TOPIC_LOWCMD, lowcmd)
            self._reader = self.channel.reader(TOPIC_LOWSTATE, lowstate)
        except BaseException:
            self.channel.close()
            raise
        self.stream = LowStateStream(self._reader, self.motors.n, o.check_state_crc, self._t0)
        if activate:
            self.open()

    def open(self) -> UnitreeHG:
        """Activate: read the state stream, check the joints, prepare the command (idempotent).

        Raises:
            NoRobotError: No state stream within ``connect_timeout_s`` (the channel is closed).
            JointOutOfLimits: A joint outside its limits (the channel is closed).
            AnotherWriterError: Another ``rt/lowcmd`` writer on the domain (the channel is closed).
        """
        if self.channel is None:
            raise HardwareError("this interface was closed; make a new one to reconnect")
        if self._active:
            return self
        try:
            self._connect()
        except BaseException:
            self.close()
            raise
        self._active = True
        return self

    # ------------------------------------------------------------------ activation
    def _connect(self) -> None:
        o, stream = self.options, self.stream
        need = 2 if o.rate_hz else RATE_STATES  # two tell a stream that goes on; more time its rate
        deadline = self._t0 + o.connect_timeout_s
        while not stream.connected(need):
            remaining = deadline - time.perf_counter()
            if remaining <= 0:
                raise NoRobotError(self._no_robot_message())
            if self._reader.wait(min(remaining, 0.05)):
                stream.drain()
        check_command_link(self._writer, self._lowcmd_writers, o.domain, o.network_interface, deadline,
                           o.connect_timeout_s, self._t0 + o.discovery_s)
        period = 1.0 / o.rate_hz if o.rate_hz else stream.measured_period()
        low, high = PERIOD_RANGE_S
        if period is None or not low <= period <= high:
            raise NoRobotError(
                f"the robot's states arrive every {(period or 0) * 1e3:.3g} ms (median), outside "
                f"{low * 1e3:g}..{high * 1e3:g} ms: not a robot's state stream, or a machine too busy to "
                "time it; give the robot's state rate with --rate-hz (the G1's is 500)")
        self._period = period
        self._clock = CycleClock(period)
        stream.start_clock(period)
        self.mode_machine = stream.mode_machine
        q = stream.q
        tol = o.limit_tolerance_rad
        out = np.flatnonzero((q < self.motors.q_low - tol) | (q > self.motors.q_high + tol))
        if out.size:
            raise JointOutOfLimits("refusing to start: " + "; ".join(
                f"{self.motors.joints[i]} at {q[i]:.4f} rad is outside its limits "
                f"[{self.motors.q_low[i]:.4f}, {self.motors.q_high[i]:.4f}]" for i in out)
                + ". Move the joint back inside its range by hand (robot powered down or damped), "
                "then retry.")
        if o.stable_gains:
            stable = stabilize(self._robot, self.motors, self.gains, self.damping_kd, period, q, self.feet)
            self.gains_lowered = stable.lowered
            if stable.lowered:
                self.gains, self.damping_kd = stable.gains, stable.damping_kd
                self.commands = MotorCommandWriter(self._robot, self.motors, self.gains)
        cmd = self._cmd_codec.message
        cmd["mode_pr"] = MODE_PR
        cmd["mode_machine"] = self.mode_machine
        motor_cmd = cmd["motor_cmd"]
        motor_cmd["mode"][: self.motors.n] = MOTOR_ENABLED
        write_damping(motor_cmd, self.damping_kd)
        self._damping_wire = self._cmd_codec.encode()  # the damping command, CRC included, made once
        if self._writer is not None:
            self._keeper = DampingKeeper(self._writer.write, self._damping_wire, period)
        # motors with gains hold where they are until a command addresses them
        hold = np.isfinite(self.gains.kp) & np.isfinite(self.gains.kd)
        motor_cmd["q"][: self.motors.n][hold] = q[hold]
        motor_cmd["kp"][: self.motors.n][hold] = self.gains.kp[hold]
        motor_cmd["kd"][: self.motors.n][hold] = self.gains.kd[hold]
        self.estimator.reset(self._reading())
        self._fresh = True

    def position_gains(self) -> dict[str, tuple[float, float]]:
        """The (kp [N m/rad], kd [N m s/rad]) sent with a position target, by joint (motors with gains)."""
        return self.gains.by_joint(self.motors)

    def _no_robot_message(self) -> str:
        o = self.options
        return (f"no robot: no state stream on {TOPIC_LOWSTATE} within {o.connect_timeout_s:g} s on DDS "
                f"domain {o.domain}, network interface {o.network_interface!r}: {self.stream.diagnosis()} "
                f"(needs {RATE_STATES} valid states, which measure its rate). Check that the robot is on "
                f"and its low-level state is published (or that `mbctl serve g1 --domain {o.domain} "
                f"--network-interface {o.network_interface}` runs; a bridge still loading: --wait-s), that "
                f"{o.network_interface!r} is the interface wired to it (ip addr; the G1's is on "
                "192.168.123.0/24), and that the domain ids match.")

    # ------------------------------------------------------------------ reading
    def _drain(self) -> None:
        """Take every waiting LowState; keep the newest valid one."""
        if self.stream.drain():
            self._fresh = True

    def _reading(self) -> Proprioception:
        stream = self.stream
        q = np.zeros(self._robot.nq)
        v = np.zeros(self._robot.nv)
        q[self.motors.idx_q] = stream.q
        v[self.motors.idx_v] = stream.dq
        self._q, self._v = q, v
        return Proprioception(stream.time_s, q[7:], v[6:], stream.imu)

    def read_state(self) -> RobotState:
        """The latest state: joints measured, base orientation from the IMU, position estimated."""
        self._drain()
        if self._clock.cycles == 0:
            self._start_loop()
        if self._fresh or self._state is None:
            reading = self._reading()
            q_base, v_base = self.estimator.update(reading)
            q, v = self._q, self._v
            q[:7] = q_base
            v[:6] = v_base
            q.setflags(write=False)
            v.setflags(write=False)
            self._state = RobotState(q, v, reading.time_s, self.estimator.estimated, self.stream.tick)
            self._fresh = False
        else:
            self.stale += 1
        if self._read_this_cycle:  # read again before the cycle's sync: this is the state it uses
            self.state_ticks[-1] = self.stream.tick
        else:
            self.state_ticks.append(self.stream.tick)
            self._read_this_cycle = True
        return self._state

    # ------------------------------------------------------------------ commanding
    def send(self, command: Command) -> None:
        """Publish ``command`` (torque, position or velocity target) as a ``LowCmd_`` with its CRC.

        After :meth:`stop` it resumes commanding (another loop): the damping thread ends first.

        Raises:
            DryRunError: The interface was opened with ``dry_run``.
            CommandError: A ctrl command, wrong size, or targets without gains.
        """
        writer = self._out
        if self._keeper is not None and self._keeper.running:
            self._keeper.stop()
        self.commands.write(command, self._motor_cmd)
        writer.write(self._cmd_codec.encode())
        self._commanded = True

    @property
    def _out(self) -> RawWriter:
        """The ``rt/lowcmd`` writer; DryRunError in a dry run (it has none)."""
        if self._writer is None:
            raise DryRunError("dry run: this interface reads the robot and never commands it")
        return self._writer

    def damp(self) -> None:
        """Send the damping command once: every motor ``kp = 0`` with its damping ``kd``, no torque."""
        self._out.write(self._damping_wire)
        self._damped = True

    def stop(self) -> None:
        """The loop is over: send the damping command every period from a thread until ``close()``.

        Nothing happens in a dry run or before the first command (the robot was never commanded).
        """
        self._end_loop()
        if self._keeper is None or not self._commanded or self.options.dry_run:
            return
        self._keeper.start()
        self._damped = True

    def sync(self) -> None:
        """Wait for the robot's next state (GIL released); check the link.

        The loop is paced by the robot's LowState stream (500 Hz on the G1, paced by its own
        clock): the cycle ends when the next state arrives, at the earliest half a period after
        it began, so the command computed from state n reaches the robot before it applies
        state n + 1's period (one period of loop delay, the least a sampled loop has). A cycle
        whose compute and IO ran past its period counts as a deadline miss.

        Raises:
            LinkLost: No new LowState for ``watchdog_periods`` periods (the damping command was
                sent if anything was commanded), or ``FIRST_CYCLE_S`` (1 s) in the first cycle.
        """
        clock, period = self._clock, self._period
        if clock.cycles == 0:
            self._start_loop()
        overran = clock.work_done() > clock.deadline
        earliest = clock.deadline - 0.5 * period
        now = time.perf_counter()
        if earliest > now:
            time.sleep(earliest - now)
        limit_s = self.options.watchdog_periods * period
        since = self.stream.last_rx
        if not self._armed:  # counted from the loop's start: connecting is not the link's silence
            limit_s = max(limit_s, FIRST_CYCLE_S)
            since = max(since, self._loop_start)
        self._drain()
        while not self._fresh:
            remaining = since + limit_s - time.perf_counter()
            if remaining <= 0 or not self._reader.wait(remaining):
                self._lost(limit_s)
            self._drain()
        clock.mark(overran)
        self._armed = True
        self._read_this_cycle = False

    def _start_loop(self) -> None:
        """Cycle 0 starts now: the clock and (``quiet_loop``) no collection, real-time priority."""
        if self.options.quiet_loop and not self._froze_gc:
            # close() unfreezes only what no one else froze before (gc.unfreeze releases all)
            self._froze_gc = gc.get_freeze_count() == 0
            gc.freeze()
            self._gc_was_on = gc.isenabled()
            gc.disable()
            self._ran_realtime = self._realtime.acquire()
        self.stream.begin_loop()
        self._clock.start()
        self._loop_start = time.perf_counter()

    def _end_loop(self) -> None:
        """The loop is over: collection back on, the thread's own priority (idempotent)."""
        self._realtime.release()
        if self._gc_was_on:
            gc.enable()
            self._gc_was_on = False

    def _lost(self, limit_s: float) -> None:
        silent_s = time.perf_counter() - self.stream.last_rx
        self.watchdog_events += 1
        if self._commanded:
            self.damp()
            acted = "sent the damping command"
        else:
            acted = "nothing had been commanded"
        raise LinkLost(
            f"link lost: no new LowState for {silent_s * 1e3:.1f} ms (limit {limit_s * 1e3:.0f} ms, "
            f"{self.options.watchdog_periods} periods of {self._period * 1e3:.3g} ms) at "
            f"t={self.time_s:.3f} s; "
            f"{acted}. The stream so far: {self.stream.diagnosis()}. Check the robot and the link on "
            f"{self.options.network_interface!r}.")

    # ------------------------------------------------------------------ RobotInterface
    @property
    def robot(self) -> Robot:
        """The model pair."""
        return self._robot

    @property
    def control_period_s(self) -> float:
        """The control period [s]: the robot's state period (measured at connect, or ``rate_hz``)."""
        return self._period

    @property
    def time_s(self) -> float:
        """The robot's time [s]: that of its newest state (its tick clock, or its arrival)."""
        return self.stream.time_s

    # ------------------------------------------------------------------ lifecycle and report
    def report(self) -> PlantReport:
        """The plant's report: the wall-clock timing, the link's counts, clamping, watchdog, damping."""
        t = self._clock.stats()  # its cycles are those started: the one under way is not complete
        timing = TimingReport(max(0, t.cycles - 1), t.period_p50_ms, t.period_p99_ms, t.period_max_ms,
                              t.deadline_misses, t.work_p99_ms, t.work_cpu_p99_ms, t.cpu_overruns, self.stale,
                              realtime=self._ran_realtime)
        c, o = self.stream.counts, self.options
        gap_p99, gap_max = self.stream.gaps_ms()
        link = LinkReport("dds", states_received=c.valid, states_lost=self.stream.messages_lost,
                          commands_lost=None, states_superseded=c.superseded, commands_superseded=None,
                          bad_crc=c.bad_crc, bad_encoding=c.bad_encoding, domain=o.domain,
                          network_interface=o.network_interface, mode_machine=self.mode_machine,
                          state_order=self.stream.order, state_rate_hz=1.0 / self._period,
                          bad_states=c.bad_states, crc_unchecked=c.crc_unchecked,
                          state_gap_p99_ms=gap_p99, state_gap_max_ms=gap_max)
        binder = self.commands.binder
        safety = SafetyReport(binder.clamped(), binder.clamped_commands, self.watchdog_events,
                              damped=None if self.options.dry_run else self._damped,
                              gains_lowered=self.gains_lowered)
        return PlantReport("dds", timing, link, safety, self.estimator.estimated)

    def close(self) -> None:
        """Stop the damping thread, damp (if anything was commanded) and leave DDS (idempotent)."""
        if self.channel is None:
            return
        try:
            self._end_loop()
            if self._keeper is not None:
                self._keeper.stop()
            if self._commanded and not self.options.dry_run:
                self.damp()
        finally:
            self.channel.close()
            self.channel = None  # type: ignore[assignment]
            if self._froze_gc:
                gc.unfreeze()
                self._froze_gc = False

    def __enter__(self) -> UnitreeHG:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()


#: The G1 over DDS: :class:`UnitreeHG` with its default table (the 29-dof G1's).
UnitreeG1 = UnitreeHG
