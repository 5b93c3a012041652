"""Watch a job's per-cycle log while the job runs: the log itself, every cycle's values, the plots' titles."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from mbctl.jobs.runner import RunContext, RunRecord


def spy_on_log(monkeypatch: pytest.MonkeyPatch, log_cls: type, run: Callable[[], RunRecord],
               per_cycle: Callable[[Any], tuple[float, ...]]) -> tuple[RunRecord, Any, np.ndarray]:
    """Run ``run()`` with ``log_cls.on_step`` and ``RunContext.save_figure`` watched.

    Returns:
        The run's record, its log (``titles``: the plots' titles as saved) and ``per_cycle(log)``
        of every cycle, read after the log's own step, as a float32 array (cycles, k).
    """
    logs: list[Any] = []
    values: list[tuple[float, ...]] = []
    on_step, save_figure = log_cls.on_step, RunContext.save_figure

    def spied(self: Any, k: int, state: Any, reference: Any, command: Any) -> bool:
        done = on_step(self, k, state, reference, command)
        values.append(per_cycle(self))
        if not logs:
            self.titles = []
            logs.append(self)
        return done

    def saved(ctx: RunContext, fig: Any, name: str) -> Any:
        logs[0].titles.append(fig.get_suptitle())
        return save_figure(ctx, fig, name)

    with monkeypatch.context() as m:
        m.setattr(log_cls, "on_step", spied)
        m.setattr(RunContext, "save_figure", saved)
        record = run()
    return record, logs[0], np.array(values, dtype=np.float32)
