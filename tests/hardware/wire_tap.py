"""A listener on ``rt/lowcmd``: every LowCmd any client sends on the test's domain, with its arrival time."""

from __future__ import annotations

import threading
import time

import numpy as np

from mbctl.hardware import default_damping
from mbctl.robots.model_pair import Robot
from mbctl.unitree import TOPIC_LOWCMD, Channel, MotorMap, low_cmd_codec
from mbctl.unitree.channel import message_types


class WireTap:
    """Records each valid LowCmd's motor records (29,) and when it was taken [s] (``time.perf_counter``).

    Args:
        domain: The test's DDS domain (loopback).
    """

    def __init__(self, domain: int):
        self.channel = Channel(domain)
        self._reader = self.channel.reader(TOPIC_LOWCMD, message_types()[0], depth=256)
        self.commands: list[np.ndarray] = []
        self.times: list[float] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        codec = low_cmd_codec()
        while not self._stop.is_set():
            if not self._reader.wait(0.01):
                continue
            for data in self._reader.take(256):
                if codec.decode(data):
                    self.commands.append(codec.message["motor_cmd"][:29].copy())
                    self.times.append(time.perf_counter())

    def wait_for(self, n: int, timeout_s: float = 30.0) -> bool:
        """Whether ``n`` commands have come (waits up to ``timeout_s``)."""
        deadline = time.monotonic() + timeout_s
        while len(self.commands) < n and time.monotonic() < deadline:
            time.sleep(0.005)
        return len(self.commands) >= n

    def wait_matched(self, timeout_s: float = 30.0) -> bool:
        """Whether discovery matched this tap with a writer of ``rt/lowcmd`` (waits up to ``timeout_s``)."""
        deadline = time.monotonic() + timeout_s
        while not self._reader.matched() and time.monotonic() < deadline:
            time.sleep(0.005)
        return self._reader.matched() > 0

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2)
        self.channel.close()

    def __enter__(self) -> WireTap:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def is_damping(cmd: np.ndarray, robot: Robot) -> bool:
    """Whether motor records ``cmd`` (29,) are the damping command: kp = 0, no target, no torque, and
    kd > 0 up to the default (lowered where the plant's motor law needs it: hardware/motor_law.py)."""
    kd = default_damping(MotorMap.for_robot(robot))
    return bool(np.all(cmd["kp"] == 0) and np.all(cmd["kd"] > 0) and np.all(cmd["kd"] <= kd * (1 + 1e-6))
                and np.all(cmd["tau"] == 0) and np.all(cmd["dq"] == 0) and np.all(cmd["mode"] == 1))


def after_the_loop(tap: WireTap, robot: Robot) -> tuple[list[bool], np.ndarray]:
    """The commands after the loop's last non-damping one: whether each is damping, and their gaps [s]."""
    damped = [is_damping(c, robot) for c in tap.commands]
    first = len(damped) - damped[::-1].index(False) if False in damped else 0
    return damped[first:], np.diff(tap.times[first:])
