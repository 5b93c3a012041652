"""The sweep's text summary: which rows did not pass and why, and the metric by row.

A sweep exits 1 when a row's run failed or diverged (its ``status`` says so) or completed outside
its bound (exit code 1: the ``error`` column then holds the run's bound, "outside its bound:
..."). :func:`summary_lines` says how many of each, and :func:`metric_table` prints the metric
(the job's main value, or ``--metric``) of every row, with the swept options, the status, the exit
code and the reason, as a fixed-width table (the first :data:`TABLE_ROWS` rows; ``sweep.csv``
holds them all).
"""

from __future__ import annotations

import math
from typing import Any

#: Rows the printed table shows at most (the rest are in sweep.csv).
TABLE_ROWS = 40
#: Characters of a row's reason the table shows (the CSV holds it whole).
WHY_CHARS = 100


def passed(row: dict[str, Any]) -> bool:
    """The row's run completed within its bound (exit code 0)."""
    return str(row.get("exit_code", "")) == "0"


def summary_lines(rows: list[dict[str, Any]]) -> list[str]:
    """How many rows did not pass, split into not completed and outside their bound ([] if none)."""
    bad = [r for r in rows if not passed(r)]
    if not bad:
        return []
    outside = sum(r.get("status") == "completed" for r in bad)
    return [f"exit 1: {len(bad)} of {len(rows)} rows did not pass: {outside} completed outside their "
            f"bound, {len(bad) - outside} not completed (failed, diverged or interrupted); the table says "
            "which and why"]


def _shown(value: Any) -> str:
    text = "" if value is None else str(value)
    try:
        number = float(text)
    except ValueError:
        return text
    return f"{number:.4g}" if math.isfinite(number) and text.lower() not in ("true", "false") else text


def metric_table(rows: list[dict[str, Any]], names: list[str], metric: str) -> list[str]:
    """The metric of every row as a fixed-width table (header first), at most :data:`TABLE_ROWS` rows."""
    columns = [*names, metric, "status", "exit"]
    cells = []
    for row in rows[:TABLE_ROWS]:
        why = "" if passed(row) else str(row.get("error") or "")
        why = why if len(why) <= WHY_CHARS else why[: WHY_CHARS - 3] + "..."
        cells.append([*(_shown(row.get(n)) for n in names), _shown(row.get(metric)) or "-",
                      str(row.get("status", "")), str(row.get("exit_code", "")), why])
    widths = [max([len(c), *(len(r[k]) for r in cells)]) for k, c in enumerate(columns)]
    lines = [f"{metric} by row:", "  " + "  ".join(c.ljust(w) for c, w in zip(columns, widths, strict=True))
             + "  why (not passed)"]
    for r in cells:
        lines.append(("  " + "  ".join(c.ljust(w) for c, w in zip(r[:-1], widths, strict=True))
                      + ("  " + r[-1] if r[-1] else "")).rstrip())
    if len(rows) > TABLE_ROWS:
        lines.append(f"  ... {len(rows) - TABLE_ROWS} more rows in sweep.csv")
    return lines
