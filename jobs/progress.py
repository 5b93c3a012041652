"""The progress bar a job shows on a terminal (rich), cheap enough to advance every control cycle."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any


@dataclass
class Progress:
    """A progress bar over a known amount of work; silent unless enabled (a terminal, not quiet).

    ``advance()`` is cheap enough for a control loop: the bar is redrawn at most every 1 % of the
    total.
    """

    enabled: bool = False
    _bar: Any = None
    _task: Any = None
    _done: int = 0
    _next: int = 0
    _step: int = 1

    def start(self, total: int, description: str) -> None:
        """Show a bar of ``total`` units labelled ``description`` (no-op when disabled)."""
        self.stop()
        self._done, self._step = 0, max(1, total // 100)
        self._next = self._step
        if not self.enabled or total <= 0:
            return
        from rich.progress import BarColumn, TimeRemainingColumn
        from rich.progress import Progress as RichProgress

        self._bar = RichProgress("[progress.description]{task.description}", BarColumn(),
                                 "{task.completed}/{task.total}", TimeRemainingColumn(),
                                 transient=True)
        self._bar.start()
        self._task = self._bar.add_task(description, total=total)

    def advance(self, n: int = 1) -> None:
        """Count ``n`` units done."""
        self._done += n
        if self._bar is not None and self._done >= self._next:
            self._bar.update(self._task, completed=self._done)
            self._next = self._done + self._step

    def set(self, done: int, total: int | None = None) -> None:
        """Set the count to ``done`` of ``total`` (callbacks that report absolute progress)."""
        if total is not None and self._bar is not None:
            self._bar.update(self._task, total=total)
        self.advance(done - self._done)

    def stop(self) -> None:
        """Remove the bar."""
        if self._bar is not None:
            self._bar.stop()
            self._bar = None
