"""A fake G1 for the interface tests: publishes LowState at 500 Hz on loopback, records every LowCmd."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from mbctl.unitree import TOPIC_LOWCMD, TOPIC_LOWSTATE, Channel, low_cmd_codec, low_state_codec
from mbctl.unitree.channel import message_types


class FakeG1:
    """Publishes a still robot's LowState every 2 ms from a thread; decodes the commands it gets.

    Change what it publishes only through :meth:`set_q` and :meth:`stop_publishing`: they take the
    lock the publishing thread holds while it builds and writes a message, so no message goes out
    with half of a change (e.g. a new q with a still good CRC).

    Args:
        domain: The test's DDS domain (loopback).
        q: Motor positions (29,) [rad].
        quat_wxyz: IMU orientation.
        bad_crc: Publish every message with a wrong CRC.
    """

    def __init__(self, domain: int, q: np.ndarray, quat_wxyz=(1.0, 0.0, 0.0, 0.0), bad_crc: bool = False):
        self.channel = Channel(domain)
        lowcmd, lowstate = message_types()
        self._writer = self.channel.writer(TOPIC_LOWSTATE, lowstate)
        self._reader = self.channel.reader(TOPIC_LOWCMD, lowcmd, depth=64)
        self._state = low_state_codec()
        m = self._state.message
        m["mode_machine"] = 5
        m["motor_state"]["q"][:29] = q
        m["imu_state"]["quaternion"] = quat_wxyz
        m["imu_state"]["accelerometer"] = (0.0, 0.0, 9.81)
        self._bad_crc = bad_crc
        self._publishing = True
        self._lock = threading.Lock()  # the published message and its flags, vs. the publishing thread
        self.commands: list[np.ndarray] = []  # each valid LowCmd's motor records
        self.bad_commands = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        cmd = low_cmd_codec()
        while not self._stop.is_set():
            with self._lock:
                if self._publishing:
                    m = self._state.message
                    m["tick"] = int(m["tick"]) + 1
                    wire = bytearray(self._state.encode())
                    if self._bad_crc:
                        wire[-4] ^= 0xFF
                    self._writer.write(bytes(wire))
            for data in self._reader.take(64):
                if cmd.decode(data):
                    self.commands.append(cmd.message["motor_cmd"][:29].copy())
                else:
                    self.bad_commands += 1
            time.sleep(0.002)

    def set_q(self, q: np.ndarray, bad_crc: bool = False) -> None:
        """Publish motor positions ``q`` (29,) [rad], with a bad CRC if ``bad_crc``, from the next message on.

        Both change together: every message sent after this returns has both, none before has either.
        """
        with self._lock:
            self._state.message["motor_state"]["q"][:29] = q
            self._bad_crc = bad_crc

    def stop_publishing(self) -> None:
        """Go silent: no LowState is sent after this returns (commands are still recorded)."""
        with self._lock:
            self._publishing = False

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2)
        self.channel.close()


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
