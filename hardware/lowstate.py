"""The robot's LowState stream as the DDS interface takes it: checks, order, rate and what went wrong.

Every LowState taken from ``rt/lowstate`` is decoded and checked before it can become the state:

- **encoding**: not little-endian XCDR1 of ``LowState_``'s size: ``bad_encoding``;
- **CRC**: a wrong CRC: ``bad_crc``. The real G1 signs its states; Unitree's simulator leaves the
  CRC 0, and such states are accepted only when the caller asks (``check_crc=False``, the CLI's
  ``--state-crc off``), counted as ``crc_unchecked``; a non-zero wrong CRC is refused even then;
- **values**: a non-finite or non-unit IMU quaternion (norm off 1 by more than
  :data:`QUAT_TOLERANCE`), non-finite gyro, accelerometer or joints: ``bad_states``, never a crash;
- **order**: a tick of 0 is a stream that does not count its states (Unitree's simulator leaves
  it 0): such states are taken in arrival order, the latest to arrive is the newest. From the first
  non-zero tick (the G1, ``mbctl serve g1``), states are ordered by tick: one whose tick is behind
  the newest's is ``superseded`` (reordered), one with the same tick is the same state again (a
  robot held still, as ``mbctl serve g1 --lockstep`` before its first command: not a new state),
  and one whose tick is further ahead than the time since the newest state can explain (a spoofed
  2^32 - 1) is a bad state (``far_ticks``, counted in ``bad_states``), not the new clock: at most
  ``tick_step`` times (twice the periods elapsed + :data:`TICK_SLACK_STATES`), the periods counted
  at the measured rate or, while connecting, at the fastest accepted one (2 kHz); while the step
  is not known yet (the first advance, e.g. of a robot held still) at most
  :data:`MAX_TICK_RATE_HZ` ticks per second elapsed + :data:`TICK_SLACK_STATES` (a microsecond
  counter; a spoof within that is not told from the robot's next state). The very first state
  cannot be judged: a spoofed one then makes every real state "behind", and the connect fails
  saying so (no robot, exit 2). The report says which order it ended in (``state_order``).

The time of a state is the robot's own once its tick advances (tick steps times the period, from
the newest state's time then, so a run's timing does not depend on when this process got round to
reading); in arrival order, from connect on, its count of new states times the measured period (a
plant publishes one a period: arrival times carry this process's and the link's jitter, which on
a loaded machine put an excitation's accelerations, and the masses identified from them, off);
and its arrival time before (while connecting, or from a tick's first advance until its step is
known).

The rate is measured at connect (:meth:`LowStateStream.measured_period`): over the first
:data:`RATE_STATES` valid arrivals (a held robot's repeats included: they come at its rate), the
mean interval between arrivals :data:`RATE_SPAN` apart, its median (a stall of either process
lengthens a few spans, a burst of queued states shortens a few), snapped to the nearest of
:data:`ROUND_RATES_HZ` within :data:`SNAP` (a robot's timer runs at a round rate: 2.06 ms measured on
a loaded machine is the G1's 2 ms), else rounded to two significant digits.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from mbctl.robots.interface import ImuReading
from mbctl.unitree.channel import RawReader
from mbctl.unitree.exceptions import WireFormatError
from mbctl.unitree.wire import low_state_codec

#: Order by the robot's tick, or by arrival where the tick does not advance.
ORDER_TICK, ORDER_ARRIVAL = "tick", "arrival"
#: Advancing states timed at connect to measure the state rate.
RATE_STATES = 26
#: States apart of the arrival intervals whose median gives the rate.
RATE_SPAN = 5
#: The rates [Hz] robots' timers run at, which a measured rate is snapped to.
ROUND_RATES_HZ = (2000.0, 1000.0, 500.0, 400.0, 250.0, 200.0, 100.0, 50.0)
#: How far [fraction] a measured period may be from a round one and still be taken for it.
SNAP = 0.1
#: The state periods [s] accepted from the measurement (0.5 ms to 50 ms: 2 kHz to 20 Hz).
PERIOD_RANGE_S = (0.5e-3, 50e-3)
#: How far the IMU quaternion's norm may be from 1 (float32 on the wire: ~1e-7 when normalised).
QUAT_TOLERANCE = 1e-3
#: A tick may run ahead of the last by at most this many states more than the time since the last
#: state explains (states the reader's queue dropped while this process was descheduled).
TICK_SLACK_STATES = 100
#: The fastest a tick may count [ticks/s] while its step is not known yet (a microsecond counter).
MAX_TICK_RATE_HZ = 1e6


@dataclass
class StreamCounts:
    """What the stream took and what it refused (each message counted once).

    Attributes:
        seen: LowState messages taken, of any kind.
        valid: States accepted as the newest.
        bad_encoding: Another encoding or size.
        bad_crc: A wrong CRC.
        bad_crc_zero: Of those, with CRC 0 (unsigned: Unitree's simulator).
        crc_unchecked: Accepted with CRC 0, unchecked (only with ``check_crc=False``).
        bad_states: Refused for their values or a tick far ahead.
        far_ticks: Of those, with a tick further ahead than the time since the newest explains.
        older: Valid but behind the newest (tick order: reordered).
        repeated: Valid with the newest's tick again (tick order: a robot held still).
    """

    seen: int = 0
    valid: int = 0
    bad_encoding: int = 0
    bad_crc: int = 0
    bad_crc_zero: int = 0
    crc_unchecked: int = 0
    bad_states: int = 0
    far_ticks: int = 0
    older: int = 0
    repeated: int = 0

    @property
    def arrivals(self) -> int:
        """Valid states that arrived, newest or not (the rate is measured on them)."""
        return self.valid + self.older + self.repeated

    @property
    def superseded(self) -> int:
        """Valid states that were not the newest when they arrived."""
        return self.older + self.repeated


class LowStateStream:
    """Takes LowStates from a reader and keeps the newest valid one (see the module docstring).

    Args:
        reader: The ``rt/lowstate`` reader.
        n_motors: Motor slots the robot uses (the table's).
        check_crc: Refuse states with CRC 0 too (False accepts them unchecked).
        t0: The interface's time origin (``time.perf_counter``) [s].
    """

    def __init__(self, reader: RawReader, n_motors: int, check_crc: bool = True, t0: float = 0.0):
        self._reader = reader
        self.check_crc = check_crc
        self.t0 = t0
        self._codec = low_state_codec()
        # the fields read every state: views of the codec's buffer (decode fills it in place), made once
        msg = self._codec.message
        motors, imu = msg["motor_state"][:n_motors], msg["imu_state"]
        self._fields = (imu["quaternion"], imu["gyroscope"], imu["accelerometer"], motors["q"], motors["dq"])
        self.counts = StreamCounts()
        self.order: str | None = None
        self.tick = 0
        self.tick_step = 0  # smallest positive tick difference seen (tick order)
        self.last_rx = -math.inf
        self.time_s = 0.0
        self.period_s: float | None = None
        self._clock: tuple[int, float] | None = None  # (tick, time) the tick clock counts from
        self._arrivals: list[float] = []
        self._base = (0, 0)  # (tick, states before it) the losses count from
        self._gaps = np.empty(1 << 20)  # between new states once the loop runs [s] (35 min at 500 Hz)
        self._n_gaps = 0
        self._loop_began = False
        self._loop_rx: float | None = None  # the time of the loop's last new state [s]
        self.q = np.zeros(n_motors)
        self.dq = np.zeros(n_motors)
        self.imu = ImuReading(np.array([1.0, 0, 0, 0]), np.zeros(3), np.zeros(3))
        self.mode_machine = 0

    def connected(self, arrivals: int) -> bool:
        """Whether ``arrivals`` valid states came, and one after the first that is not behind it."""
        c = self.counts
        return c.arrivals >= arrivals and c.valid + c.repeated >= 2

    def drain(self) -> bool:
        """Take every waiting LowState; whether a newer valid one was accepted."""
        fresh = False
        for data in self._reader.take(32):
            fresh |= self._take(data, time.perf_counter())
        return fresh

    def _take(self, data: bytes, now: float) -> bool:
        c, codec = self.counts, self._codec
        c.seen += 1
        try:
            ok = codec.decode(data)
        except WireFormatError:
            c.bad_encoding += 1
            return False
        msg = codec.message
        if not ok:
            if int(msg["crc"]) != 0 or self.check_crc:
                c.bad_crc += 1
                c.bad_crc_zero += int(msg["crc"]) == 0
                return False
            c.crc_unchecked += 1
        # copies in float64 (the fields are views of the buffer the next state is decoded into)
        quat, gyro, accel, q, dq = (np.array(f, dtype=float) for f in self._fields)
        # every value finite: their sum in float64 is (float32 values cannot overflow it)
        finite = math.isfinite(quat.sum() + gyro.sum() + accel.sum() + q.sum() + dq.sum())
        w, x, y, z = quat.tolist()
        if not finite or abs(math.sqrt(w * w + x * x + y * y + z * z) - 1.0) > QUAT_TOLERANCE:
            c.bad_states += 1
            return False
        tick = int(msg["tick"])
        if self.period_s is None:
            self._arrivals.append(now)
        if not self._newer(tick, now):
            return False
        c.valid += 1
        self.time_s = self._time_of(tick, now)
        if self._loop_rx is not None and self._n_gaps < self._gaps.size:  # the loop runs: its waits
            self._gaps[self._n_gaps] = now - self._loop_rx
            self._n_gaps += 1
        if self._loop_rx is not None or self._loop_began:
            self._loop_rx = now
        self.tick, self.last_rx = tick, now
        self.q, self.dq = q, dq
        self.imu = ImuReading(quat, gyro, accel)
        self.mode_machine = int(msg["mode_machine"])
        return True

    def _newer(self, tick: int, now: float) -> bool:
        """Whether a valid state with ``tick`` is newer than the newest (counting the ones that are not)."""
        c = self.counts
        if self.order is None or (self.order == ORDER_ARRIVAL and tick == 0):
            self.order = ORDER_ARRIVAL if tick == 0 else ORDER_TICK
            if self.order == ORDER_TICK:
                self._base = (tick, c.valid)  # losses count from here
            return True
        if self.order == ORDER_ARRIVAL:  # the first non-zero tick: the robot's clock starts
            self.order = ORDER_TICK
            self._base = (tick, c.valid)
            self._clock = None  # the count's clock ends; the tick's starts once its step is known
            return True
        step = tick - self.tick
        if step < 0:
            c.older += 1
            return False
        if step == 0:
            c.repeated += 1
            return False
        if step > self._max_step(now):
            c.bad_states += 1
            c.far_ticks += 1
            return False
        if not self.tick_step:
            self.tick_step = step
            if self.period_s is not None:  # the tick clock starts from the newest state
                self._clock = (self.tick, self.time_s)
        self.tick_step = min(self.tick_step, step)
        return True

    def _max_step(self, now: float) -> float:
        """The furthest [ticks] a state arriving at ``now`` may be ahead of the newest (module docstring)."""
        elapsed = max(0.0, now - self.last_rx)
        if not self.tick_step:
            return MAX_TICK_RATE_HZ * elapsed + TICK_SLACK_STATES
        period = self.period_s if self.period_s is not None else PERIOD_RANGE_S[0]
        return self.tick_step * (2 * math.ceil(elapsed / period) + TICK_SLACK_STATES)

    def _time_of(self, tick: int, now: float) -> float:
        """The state's time [s]: on the robot's clock once it runs, else its arrival.

        The robot's clock is its tick, or in arrival order the count of new states.
        """
        if self._clock is None:
            return now - self.t0
        mark, time0 = self._clock
        if self.order == ORDER_ARRIVAL:
            return time0 + (self.counts.valid - mark) * self.period_s  # type: ignore[operator]
        return time0 + (tick - mark) / self.tick_step * self.period_s  # type: ignore[operator]

    def measured_period(self) -> float | None:
        """The state period [s] from the arrivals so far (None before :data:`RATE_STATES`)."""
        t = np.asarray(self._arrivals)
        if t.size < RATE_STATES:
            return None
        spans = (t[RATE_SPAN:] - t[:-RATE_SPAN]) / RATE_SPAN
        period = float(np.median(spans))
        if period <= 0:
            return period
        nearest = 1.0 / min(ROUND_RATES_HZ, key=lambda hz: abs(1.0 / hz - period))
        if abs(period - nearest) <= SNAP * nearest:
            return nearest
        digits = 1 - math.floor(math.log10(period))
        return round(period, digits)

    def start_clock(self, period_s: float) -> None:
        """The loop's period [s] from now on; the robot's clock counts from the newest state.

        The robot's clock is its tick, or in arrival order the count of new states.
        """
        self.period_s = period_s
        self._arrivals.clear()
        if self.order == ORDER_TICK and self.tick_step:
            self._clock = (self.tick, self.time_s)
        elif self.order == ORDER_ARRIVAL:
            self._clock = (self.counts.valid, self.time_s)

    def begin_loop(self) -> None:
        """The loop begins: the waits between new states count from its first new state on."""
        self._loop_began = True

    def gaps_ms(self) -> tuple[float, float] | tuple[None, None]:
        """The 99th percentile and the longest [ms] of the waits between new states in the loop.

        What the watchdog is compared with; None before two states.
        """
        if not self._n_gaps:
            return None, None
        gaps = self._gaps[: self._n_gaps] * 1e3
        return float(np.percentile(gaps, 99)), float(gaps.max())

    @property
    def messages_lost(self) -> int:
        """States sent but never received (gaps in the tick; 0 in arrival order: unknown there)."""
        if self.order != ORDER_TICK or not self.tick_step:
            return 0
        base_tick, valid_before = self._base
        return max(0, (self.tick - base_tick) // self.tick_step + 1 - (self.counts.valid - valid_before))

    def diagnosis(self) -> str:
        """What was seen on the topic, for a "no robot" or "link lost" message."""
        c = self.counts
        if c.seen == 0:
            return "nothing was seen on the domain"
        parts = [f"{c.seen} LowState messages seen"]
        if c.bad_crc:
            parts.append(f"{c.bad_crc} with a bad CRC" + (
                f" ({c.bad_crc_zero} with CRC 0: unsigned, as Unitree's simulator sends them; "
                "`--state-crc off` accepts those)" if c.bad_crc_zero else ""))
        if c.bad_encoding:
            parts.append(f"{c.bad_encoding} in another encoding")
        if c.bad_states - c.far_ticks:
            parts.append(f"{c.bad_states - c.far_ticks} with bad values (IMU quaternion not finite and unit, "
                         "non-finite joints or IMU)")
        if c.far_ticks:
            parts.append(f"{c.far_ticks} with a tick further ahead of the newest ({self.tick}) than the time "
                         "since it allows (spoofed, or another robot's: refused)")
        if c.valid:
            parts.append(f"{c.valid} valid")
        if c.older or c.repeated:
            parts.append(f"{c.superseded} that never advance (their tick not past {self.tick}: {c.older} "
                         f"behind, {c.repeated} the same)")
        return ", ".join(parts)
