"""The damping command kept on the wire between the end of a loop and ``close()``, from its own thread.

When a job's control loop ends (done, failed, interrupted) the process still has work to do (the
report, the plots: seconds, tens on a loaded machine) before it closes the interface. A robot's
motors keep applying the last command they got, so a loop that simply stops leaves a standing
robot on its last torques with no feedback. :class:`DampingKeeper` publishes the damping command
(``kp = 0``, ``kd`` per motor, no torque; prepared once, CRC included) every period from a thread
of its own until it is stopped, so what the main thread does meanwhile cannot starve it (the
write is a few microseconds, GIL released while it waits; while it runs, the interpreter asks a
thread holding the GIL to let go after a quarter period instead of 5 ms).
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Callable

from mbctl.unitree.exceptions import UnitreeError


class DampingKeeper:
    """Publishes one prepared message every ``period_s`` from a daemon thread until :meth:`stop`.

    Args:
        write: Publishes wire bytes (the interface's ``rt/lowcmd`` writer).
        payload: The damping command's wire bytes.
        period_s: Its period [s] (the loop's).
    """

    def __init__(self, write: Callable[[bytes], None], payload: bytes, period_s: float):
        self._write = write
        self._payload = payload
        self.period_s = float(period_s)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        #: Damping commands sent by the thread.
        self.sent = 0
        #: Why the thread ended early (the channel failed), or None.
        self.error: str | None = None

    @property
    def running(self) -> bool:
        """Whether the thread is sending."""
        return self._thread is not None

    def start(self) -> None:
        """Send the damping command now, then every period from the thread (idempotent)."""
        if self._thread is not None:
            return
        self._stop.clear()
        self._send()
        # the main thread may hold the GIL in long stretches (plots): ask it back at a quarter period
        self._switch_s = sys.getswitchinterval()
        sys.setswitchinterval(min(self._switch_s, self.period_s / 4))
        self._thread = threading.Thread(target=self._run, name="mbctl-damping", daemon=True)
        self._thread.start()

    def _send(self) -> bool:
        try:
            self._write(self._payload)
        except UnitreeError as exc:
            self.error = str(exc)
            return False
        self.sent += 1
        return True

    def _run(self) -> None:
        next_s = time.perf_counter() + self.period_s
        while not self._stop.wait(max(0.0, next_s - time.perf_counter())):
            if not self._send():
                return
            next_s += self.period_s
            now = time.perf_counter()
            if next_s < now:  # this thread was held up: no burst of catch-up sends
                next_s = now + self.period_s

    def stop(self) -> None:
        """Stop sending and wait for the thread (idempotent)."""
        if self._thread is None:
            return
        self._stop.set()
        self._thread.join()
        self._thread = None
        sys.setswitchinterval(self._switch_s)
