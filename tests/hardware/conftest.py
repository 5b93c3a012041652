"""A fake G1 for the interface tests: publishes LowState at 500 Hz on loopback, records every LowCmd."""

from __future__ import annotations

import sys
import threading
import time

import numpy as np
import pytest

from mbctl.unitree import TOPIC_LOWCMD, TOPIC_LOWSTATE, Channel, low_cmd_codec, low_state_codec
from mbctl.unitree.channel import message_types

#: The fake's state period [s] (the G1's 500 Hz).
PERIOD_S = 0.002


class FakeG1:
    """Publishes a still robot's LowState every period from a thread; decodes the commands it gets.

    Change what it publishes only through :meth:`set_q`, :meth:`once` and :meth:`stop_publishing`:
    they take the lock the publishing thread holds while it builds and writes a message, so no
    message goes out with half of a change (e.g. a new q with a still good CRC).

    Args:
        domain: The test's DDS domain (loopback).
        q: Motor positions (29,) [rad].
        quat_wxyz: IMU orientation.
        bad_crc: Publish every message with a wrong CRC.
        unsigned: Leave every message's CRC 0, as Unitree's simulator does.
        period_s: Its state period [s].
        tick_step: How much the tick advances per message (0: never; negative: it runs backwards).
        tick0: The first message's tick (0 with ``tick_step`` 0: Unitree's simulator).
        held: Hold the tick until the first command (as ``mbctl serve g1 --lockstep``).
    """

    def __init__(self, domain: int, q: np.ndarray, quat_wxyz=(1.0, 0.0, 0.0, 0.0), bad_crc: bool = False,
                 unsigned: bool = False, period_s: float = PERIOD_S, tick_step: int = 1,
                 tick0: int = 1 << 20, held: bool = False):
        self.channel = Channel(domain)
        self._held = held
        lowcmd, lowstate = message_types()
        self._writer = self.channel.writer(TOPIC_LOWSTATE, lowstate)
        self._reader = self.channel.reader(TOPIC_LOWCMD, lowcmd, depth=64)
        self._state = low_state_codec()
        m = self._state.message
        m["mode_machine"] = 5
        m["tick"] = tick0 - tick_step
        m["motor_state"]["q"][:29] = q
        m["imu_state"]["quaternion"] = quat_wxyz
        m["imu_state"]["accelerometer"] = (0.0, 0.0, 9.81)
        self._bad_crc, self._unsigned = bad_crc, unsigned
        self.period_s, self._tick_step = period_s, tick_step
        self._once: dict[str, object] = {}
        self._publishing = True
        self._lock = threading.Lock()  # the published message and its flags, vs. the publishing thread
        self.commands: list[np.ndarray] = []  # each valid LowCmd's motor records
        self.command_times: list[float] = []  # when each was taken (time.perf_counter) [s]
        self.bad_commands = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _publish(self) -> None:
        m = self._state.message
        if not (self._held and not self.commands):
            m["tick"] = int(m["tick"]) + self._tick_step
        saved = {}
        for field, value in self._once.items():  # this message only
            saved[field] = m["imu_state"][field].copy() if field == "quaternion" else m[field].copy()
            if field == "quaternion":
                m["imu_state"]["quaternion"] = value
            else:
                m[field] = value
        wire = bytearray(self._state.encode())
        if self._unsigned:
            wire[-4:] = b"\0\0\0\0"
        elif self._bad_crc:
            wire[-4] ^= 0xFF
        self._writer.write(bytes(wire))
        for field, value in saved.items():
            if field == "quaternion":
                m["imu_state"]["quaternion"] = value
            else:
                m[field] = value
        self._once = {}

    def _run(self) -> None:
        cmd = low_cmd_codec()
        next_s = time.perf_counter()
        while not self._stop.is_set():
            with self._lock:
                if self._publishing:
                    self._publish()
            for data in self._reader.take(64):
                if cmd.decode(data):
                    self.commands.append(cmd.message["motor_cmd"][:29].copy())
                    self.command_times.append(time.perf_counter())
                else:
                    self.bad_commands += 1
            next_s += self.period_s  # a timer's grid, as a robot's: no drift from the work done
            now = time.perf_counter()
            if next_s < now:  # held up: go on from now, no burst of catch-up states (as a robot)
                next_s = now
            time.sleep(next_s - now)

    def set_q(self, q: np.ndarray, bad_crc: bool = False) -> None:
        """Publish motor positions ``q`` (29,) [rad], with a bad CRC if ``bad_crc``, from the next message on.

        Both change together: every message sent after this returns has both, none before has either.
        """
        with self._lock:
            self._state.message["motor_state"]["q"][:29] = q
            self._bad_crc = bad_crc

    def once(self, **fields) -> None:
        """Give the next message these values (``tick``, ``quaternion``), then go on as before."""
        with self._lock:
            self._once = dict(fields)

    def stop_publishing(self) -> None:
        """Go silent: no LowState is sent after this returns (commands are still recorded)."""
        with self._lock:
            self._publishing = False

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2)
        self.channel.close()


@pytest.fixture(autouse=True)
def short_gil_slices():
    """The interpreter hands the GIL round every 0.2 ms instead of every 5 ms, during each test here.

    The fake robot publishes from a thread of the test's own process, beside the client under test:
    with Python's default switch interval (5 ms) a busy client thread held it off for longer than
    its 2 ms period, and a loaded CI measured the fake's rate as 400 Hz. A robot runs on its own
    timer; this keeps the fake near one.
    """
    saved = sys.getswitchinterval()
    sys.setswitchinterval(2e-4)
    yield
    sys.setswitchinterval(saved)


@pytest.fixture
def fake_g1(dds_domain, g1):
    """Start a fake G1 at the ``stand`` keyframe: ``fake_g1(**kwargs)``; all are closed at the end."""
    made: list[FakeG1] = []

    def make(**kwargs) -> FakeG1:
        q = kwargs.pop("q", g1.keyframe_q("stand")[7:])
        fake = FakeG1(dds_domain, q, **kwargs)
        made.append(fake)
        return fake

    yield make
    for fake in made:
        fake.close()
