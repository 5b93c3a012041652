"""Run one job over a grid of option values on a Dask cluster: one task, one run folder, one row.

The Cartesian product of the swept values (times the seeds) runs as Dask tasks, on a local
cluster of ``workers`` processes with one thread each, or on an existing cluster given by its
scheduler address. Each task runs the job through :func:`~mbctl.jobs.runner.run_job` into
``DIR/runs/<name=value,...>/`` and returns the report's status and values; a worker loads each
robot once and keeps it for its later tasks.

The sweep folder holds:

- ``sweep.csv``: one row per combination: the swept options (named as the options), the job's
  report values (named as in its report), then ``status``, ``exit_code``, ``error`` and
  ``run_dir``. It is rewritten as each task finishes, so an interrupted sweep keeps its rows.
- ``sweep.json``: versions, the cluster, wall time, counts and the failures.
- ``sweep.png``: the metric over one option (mean and std over the rest) or a heat map over two.

A task that fails is a row with its status and error, never a lost sweep. Ctrl-C (or SIGTERM)
cancels the remaining tasks and still writes the finished rows (exit 130). ``resume`` keeps the
rows of ``sweep.csv`` whose run completed or diverged and runs the others. It trusts a row only
if the line is whole and its run folder's report agrees with it (a torn line runs again), and it
keeps the rows of an earlier grid that this one does not hold (after this grid's rows).
"""

from __future__ import annotations

import contextlib
import csv
import functools
import hashlib
import io
import itertools
import json
import math
import re
import sys
import time
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any

from mbctl.exceptions import ToolkitError
from mbctl.jobs.catalog import CatalogEntry, RobotSource, SweepInputError, entry
from mbctl.jobs.exceptions import JobError
from mbctl.jobs.run_folder import REPORT_NAME, check_output_dir, clear_previous_run, folder_lock, refuse_link
from mbctl.jobs.runner import (
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_OUT_OF_BOUND,
    Interrupted,
    Job,
    Progress,
    run_job,
    sigterm_as_interrupt,
)
from mbctl.jobs.sweep_cluster import NO_DASK, SweepSetupError, cluster_section, open_client, parse_scheduler
from mbctl.limits import MAX_SWEEP_TASKS, check_limit
from mbctl.robots.model_pair import Robot
from mbctl.robots.registry import load_robot
from mbctl.sim.atomic import read_text_nofollow, write_json_atomic, write_text_atomic
from mbctl.sim.report import package_versions

CSV_NAME = "sweep.csv"
JSON_NAME = "sweep.json"
PLOT_NAME = "sweep.png"
RUNS = "runs"
#: The columns after the values.
TAIL = ("status", "exit_code", "error", "run_dir")
#: Statuses a resumed sweep does not run again.
DONE = ("completed", "diverged")


@dataclass(frozen=True)
class SweepConfig:
    """One sweep.

    Attributes:
        job: The command name (``demo``).
        grid: Option name -> its values (parsed, see :func:`mbctl.jobs.catalog.parse_grid`).
        output_dir: The sweep folder.
        workers: Local worker processes (one thread each); ignored with ``scheduler``.
        scheduler: Address of an existing Dask scheduler (``tcp://HOST:PORT``), or None.
        dashboard: Serve the Dask dashboard (local cluster only).
        resume: Keep the done rows of an earlier ``sweep.csv`` in the folder.
        metric: The report value to plot (default: the job's main value).
        connect_timeout_s: How long [s] to wait for ``scheduler`` to answer as a Dask scheduler.
        force: Run more than :data:`~mbctl.limits.MAX_SWEEP_TASKS` tasks.
    """

    job: str
    grid: dict[str, list[Any]]
    output_dir: Path
    workers: int = 2
    scheduler: str | None = None
    dashboard: bool = False
    resume: bool = False
    metric: str | None = None
    connect_timeout_s: float = 10.0
    force: bool = False

    def __post_init__(self) -> None:
        if self.workers < 1:
            raise SweepInputError(f"--workers must be >= 1; got {self.workers}")
        if not 0 < self.connect_timeout_s <= 600:
            raise SweepInputError(f"--connect-timeout must be in (0, 600] s; got {self.connect_timeout_s}")


@dataclass
class SweepResult:
    """What a sweep wrote.

    Attributes:
        status: completed or interrupted.
        rows: Every row (done earlier and now), in grid order.
        ran: Tasks this sweep finished; skipped: rows of this grid kept from an earlier sweep.
        failures: Rows whose status is not completed.
        earlier: Rows of an earlier sweep (``--resume``) whose combination this grid does not
            hold: kept in sweep.csv after this grid's rows (not in ``rows``).
        unsound: Rows of the earlier sweep.csv that were torn or did not match their run folder:
            dropped (run again where this grid holds them).
        files: sweep.csv, sweep.json and (if drawn) sweep.png.
        wall_time_s: Wall time [s] from submitting the first task to the last result.
        note: Why no plot was drawn, if none was.
        metric: The report value plotted and tabulated.
    """

    status: str
    rows: list[dict[str, Any]]
    ran: int
    skipped: int
    failures: list[dict[str, Any]]
    files: dict[str, Path] = field(default_factory=dict)
    wall_time_s: float = 0.0
    note: str | None = None
    earlier: list[dict[str, Any]] = field(default_factory=list)
    unsound: int = 0
    metric: str = ""

    @property
    def exit_code(self) -> int:
        """130 interrupted; 1 if a row failed or is outside its bound; 0 otherwise."""
        if self.status == "interrupted":
            return EXIT_INTERRUPTED
        bad = any(str(r.get("exit_code")) not in ("", str(EXIT_OK)) for r in self.rows)
        return EXIT_OUT_OF_BOUND if bad else EXIT_OK


def combinations(grid: dict[str, list[Any]]) -> list[dict[str, Any]]:
    """The Cartesian product of the grid, the last option varying fastest."""
    names = list(grid)
    return [dict(zip(names, values, strict=True)) for values in itertools.product(*grid.values())]


def cell(value: Any) -> str:
    """A value as a CSV cell: '' for None, JSON for lists and dicts, repr-exact floats."""
    if value is None:
        return ""
    if isinstance(value, (list, tuple, dict)):
        return json.dumps(value)
    return str(value)


def run_name(combo: dict[str, Any]) -> str:
    """The run folder name ``name=value,...``.

    Characters unsafe in a file name become ``_`` and long names are cut; either adds a hash of
    the values, so two combinations never share a folder.
    """
    text = ",".join(f"{k}={cell(v) or 'none'}" for k, v in combo.items())
    name = re.sub(r"[^A-Za-z0-9._=,+-]", "_", text)
    if name != text or len(name) > 120:  # changed: a hash of the values keeps two runs apart
        name = f"{name[:120]}-{hashlib.sha1(text.encode()).hexdigest()[:8]}"
    return name


@functools.lru_cache(maxsize=8)
def cached_robot(source: RobotSource) -> Robot:
    """The robot from ``source``, loaded once per process (a worker keeps it for its tasks)."""
    return load_robot(source.name, source.scene, gravity=source.gravity, model_dir=source.model_dir)


def job_with_cached_robot(spec: CatalogEntry, params: Any) -> Job[Any]:
    """``spec``'s job, preparing with the process's cached robot where the job takes one."""
    if spec.prepare_with_robot is None or spec.robot_source is None:
        return spec.job
    robot = cached_robot(spec.robot_source(params))
    prepare = spec.prepare_with_robot
    return Job(spec.name, lambda p: prepare(p, robot))


def run_task(job: str, values: dict[str, Any], run_dir: str) -> dict[str, Any]:
    """Run ``job`` with CLI-named ``values`` into ``run_dir`` (in a worker); never raises.

    Returns:
        ``status``, ``exit_code``, ``error`` and the report's ``values``.
    """
    try:
        spec = entry(job)
        params = spec.params(values)
        record = run_job(job_with_cached_robot(spec, params), params, Path(run_dir), quiet=True)
        error = record.message
        if record.status == "completed" and record.outcome is not None and not record.outcome.passed:
            error = f"outside its bound: {record.outcome.bound}"  # why the row exits 1
        return {"status": record.status, "exit_code": record.exit_code, "error": error,
                "values": json.loads(json.dumps(record.values, default=str))}
    except Exception as exc:  # noqa: BLE001 - any failure is the row's error, never a lost sweep
        return {"status": "failed", "exit_code": EXIT_OUT_OF_BOUND, "error": f"{type(exc).__name__}: {exc}",
                "values": {}}


def _row(combo: dict[str, Any], result: dict[str, Any], run_dir: Path) -> dict[str, Any]:
    row: dict[str, Any] = {k: cell(v) for k, v in combo.items()}
    row.update({k: cell(v) for k, v in result.get("values", {}).items() if k not in combo})
    row.update(status=result["status"], exit_code=result["exit_code"], error=result.get("error") or "",
               run_dir=str(run_dir))
    return row


def _key(row: dict[str, Any], names: list[str]) -> tuple[str, ...]:
    return tuple(cell(row[n]) for n in names)


def _row_problem(row: dict[Any, Any], names: list[str], folder: Path) -> str | None:
    """Why an earlier ``sweep.csv`` row cannot be trusted (torn, edited, or its run gone), or None.

    A row is sound if it has every column and no extra one, an integer exit code and a
    ``run_dir`` that is its own run folder (``DIR/runs/<name>``); a row whose status a resumed
    sweep keeps (completed, diverged) also needs that folder's report to have its status.
    """
    if None in row or any(v is None for v in row.values()):
        return "its field count is not the header's (a torn or edited line)"
    if not re.fullmatch(r"-?\d+", row["exit_code"]):
        return f"exit_code {row['exit_code']!r} is not an integer"
    name = run_name({n: row[n] for n in names})
    if Path(row["run_dir"]).name != name:
        return f"run_dir {row['run_dir']!r} is not its run folder {name!r}"
    if row["status"] not in DONE:
        return None
    report = folder / RUNS / name / REPORT_NAME
    try:
        status = json.loads(read_text_nofollow(report)).get("status")
    except (OSError, ValueError, AttributeError):
        return f"{report} is missing or unreadable"
    if status != row["status"]:
        return f"its run's report says {status!r}, the row {row['status']!r}"
    return None


def read_earlier_rows(path: Path, names: list[str]) -> tuple[dict[tuple[str, ...], dict[str, Any]], int]:
    """The sound rows of an earlier ``sweep.csv`` by their parameter values, and the count of the others.

    Rows that fail :func:`_row_problem` (a line cut short by a crash or an edit, a run folder that
    is gone) are left out, so their combination runs again. ``run_dir`` is set to where the run
    folder is now (the sweep folder may have moved).

    Raises:
        SweepInputError: The file's parameter columns are not this sweep's, or it is not a sweep's
            CSV.
    """
    if not path.exists():
        return {}, 0
    try:
        text = read_text_nofollow(path)
    except (OSError, UnicodeDecodeError) as exc:
        raise SweepInputError(f"cannot read {path} to resume: {exc}; drop --resume or choose another "
                              "--output") from None
    reader = csv.DictReader(io.StringIO(text, newline=""))
    header = list(reader.fieldnames or [])
    if header[:len(names)] != names:
        raise SweepInputError(f"{path} has the columns {', '.join(header[:len(names)])}, not this "
                              f"sweep's parameters {', '.join(names)}; drop --resume or choose "
                              "another --output")
    if header[-len(TAIL):] != list(TAIL):
        raise SweepInputError(f"{path} does not end its header with {', '.join(TAIL)}: not a sweep's "
                              "CSV (or cut inside its header); drop --resume or choose another --output")
    sound, unsound = {}, 0
    for row in reader:
        if _row_problem(row, names, path.parent) is None:
            row["run_dir"] = str(path.parent / RUNS / run_name({n: row[n] for n in names}))
            sound[_key(row, names)] = dict(row)
        else:
            unsound += 1
    return sound, unsound


def write_csv(path: Path, rows: list[dict[str, Any]], names: list[str]) -> Path:
    """Write ``rows`` (parameters, values in first-seen order, then the tail columns) atomically."""
    values: dict[str, None] = {}
    for row in rows:
        values.update({k: None for k in row if k not in names and k not in TAIL})
    buf = io.StringIO()
    writer = csv.DictWriter(buf, [*names, *values, *TAIL], restval="", lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    return write_text_atomic(path, buf.getvalue())


def check_runs_folder(folder: Path) -> None:
    """OutputError if ``DIR/runs``, a run folder in it or a sweep file is a symbolic link."""
    for name in (CSV_NAME, JSON_NAME, PLOT_NAME, RUNS):
        refuse_link(folder / name)
    runs = folder / RUNS
    if runs.is_dir():
        for run in runs.iterdir():
            refuse_link(run)


def _clear_previous_sweep(folder: Path) -> None:
    """Remove an earlier sweep's files and what its runs made (run folders left empty go too).

    Each run folder is cleared as the job runner clears a folder (only the files its report
    lists with their SHA-256), so a file the sweep did not make is never removed.
    """
    for name in (CSV_NAME, JSON_NAME, PLOT_NAME):
        (folder / name).unlink(missing_ok=True)
    runs = folder / RUNS
    if runs.is_dir():
        for run in runs.iterdir():
            if run.is_dir() and not run.is_symlink() and (run / REPORT_NAME).exists():
                with folder_lock(run):
                    clear_previous_run(run)
                with contextlib.suppress(OSError):
                    run.rmdir()  # only if empty


def versions() -> dict[str, str]:
    """The versions a sweep depends on: mbctl, dask, distributed, mujoco, pin, python."""
    found = package_versions()
    extra = {}
    for name in ("dask", "distributed"):
        try:
            extra[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            extra[name] = "absent"
    return {"mbctl": found["mbctl"], **extra, "mujoco": found["mujoco"], "pin": found["pin"],
            "python": sys.version.split()[0]}


def prepare_sweep(config: SweepConfig) -> tuple[CatalogEntry, list[dict[str, Any]]]:
    """Check every combination's parameters before any task runs (bad input: nothing runs).

    Raises:
        SweepInputError: Unknown job, option or metric.
        SizeLimitError: More than ``MAX_SWEEP_TASKS`` combinations without ``force``.
        ToolkitError: A combination the job's parameters reject (the message names the values).
    """
    spec = entry(config.job)
    tasks = math.prod(len(values) for values in config.grid.values())
    if not config.force:
        check_limit("the grid", tasks, MAX_SWEEP_TASKS, " tasks",
                    f"{' x '.join(f'{len(v)} {k}' for k, v in config.grid.items())}; split the grid, "
                    "or give --force to run it anyway")
    if "dds" in [str(v) for v in config.grid.get("interface", [])]:
        raise SweepInputError("interface=dds: a sweep runs its tasks in parallel on in-process plants, and "
                              "one robot (or `mbctl serve g1`) takes one controller at a time; sweep the "
                              "link in process (latency_ms, jitter_ms, drop, imu_noise)")
    combos = combinations(config.grid)
    for combo in combos:
        try:
            spec.params(combo)
        except JobError:
            raise
        except ToolkitError as exc:
            raise SweepInputError(f"{run_name(combo)}: {exc}") from None
    return spec, combos


def run_sweep(config: SweepConfig, progress: Progress | None = None, client: Any = None) -> SweepResult:
    """Run the sweep; write sweep.csv, sweep.json and sweep.png into ``config.output_dir``.

    Args:
        config: The sweep.
        progress: A bar over the tasks.
        client: An open Dask client to use instead of opening one from ``config`` (tests).

    Returns:
        The result (status, rows, counts, files).

    Raises:
        SweepInputError: Bad input, found before any task runs.
        SweepSetupError: Dask missing or the cluster unreachable.
        OutputError: The folder is not usable or another process holds it.
    """
    spec, combos = prepare_sweep(config)
    if config.scheduler is not None and client is None:
        try:
            parse_scheduler(config.scheduler)  # a malformed address: nothing written
        except ImportError:
            raise SweepSetupError(NO_DASK) from None
    names = list(config.grid)
    folder = check_output_dir(config.output_dir)
    progress = progress or Progress()
    with folder_lock(folder):
        check_runs_folder(folder)
        earlier, unsound = read_earlier_rows(folder / CSV_NAME, names) if config.resume else ({}, 0)
        if not config.resume:
            _clear_previous_sweep(folder)
        keys = [_key(c, names) for c in combos]
        # rows of this grid found earlier (a failed one stays until its rerun replaces it)
        rows: dict[tuple[str, ...], dict[str, Any]] = {k: earlier[k] for k in keys if k in earlier}
        todo = [(k, c) for k, c in zip(keys, combos, strict=True)
                if rows.get(k, {}).get("status") not in DONE]
        skipped = len(keys) - len(todo)
        # rows of an earlier grid that this one does not hold: kept, after this grid's rows
        in_grid = set(keys)
        extra = [r for k, r in earlier.items() if k not in in_grid]
        status, ran = "completed", 0

        def every_row() -> list[dict[str, Any]]:
            return [rows[k] for k in keys if k in rows] + extra

        def flush() -> None:
            write_csv(folder / CSV_NAME, every_row(), names)

        with open_client(config) if client is None else contextlib.nullcontext((client, None)) as opened:
            dask_client, cluster = opened
            cluster = cluster or cluster_section(dask_client)
            t0 = time.perf_counter()
            futures: dict[Any, tuple[tuple[str, ...], dict[str, Any]]] = {}
            progress.start(len(todo), f"sweep {spec.name}")
            try:
                with sigterm_as_interrupt():
                    from dask.distributed import as_completed

                    for key, combo in todo:
                        run_dir = folder / RUNS / run_name(combo)
                        fut = dask_client.submit(run_task, spec.name, combo, str(run_dir), pure=False)
                        futures[fut] = (key, combo)
                    for fut in as_completed(list(futures)):
                        key, combo = futures[fut]
                        run_dir = folder / RUNS / run_name(combo)
                        try:
                            result = fut.result()
                        except Exception as exc:  # noqa: BLE001 - a lost worker: the row says so
                            result = {"status": "failed", "exit_code": EXIT_OUT_OF_BOUND,
                                      "error": f"{type(exc).__name__}: {exc}"}
                        rows[key] = _row(combo, result, run_dir)
                        ran += 1
                        flush()
                        progress.advance()
            except (KeyboardInterrupt, Interrupted):
                status = "interrupted"
                dask_client.cancel([f for f in futures if not f.done()])
            finally:
                progress.stop()
        wall = time.perf_counter() - t0
        ordered = [rows[k] for k in keys if k in rows]
        result = SweepResult(status, ordered, ran, skipped,
                             [r for r in ordered if r["status"] != "completed"], wall_time_s=wall,
                             earlier=extra, unsound=unsound, metric=config.metric or spec.main_value)
        result.files["csv"] = write_csv(folder / CSV_NAME, every_row(), names)
        plot = _plot(spec, config, every_row(), names, folder / PLOT_NAME)
        if plot is not None:
            result.files["plot"] = plot
        else:
            result.note = _no_plot_reason(config.metric or spec.main_value, ordered, names)
        result.files["json"] = write_json_atomic(folder / JSON_NAME, {
            "job": spec.name, "status": status,
            "grid": {k: [cell(v) for v in vs] for k, vs in config.grid.items()},
            "tasks": len(combos), "submitted": len(todo), "ran": result.ran, "skipped": skipped,
            "earlier_grid_rows": len(extra), "unsound_rows": unsound,
            "wall_time_s": wall, "metric": config.metric or spec.main_value,
            "versions": versions(), "cluster": cluster,
            "failures": [{k: r[k] for k in [*names, "status", "error", "run_dir"]} for r in result.failures],
            "outside_bound": [{k: r[k] for k in [*names, "error", "run_dir"]} for r in ordered
                              if r["status"] == "completed" and str(r["exit_code"]) != str(EXIT_OK)],
            "outputs": {role: p.name for role, p in result.files.items()},
        })
    return result


def _no_plot_reason(metric: str, rows: list[dict[str, Any]], names: list[str]) -> str:
    keys = [k for k in dict.fromkeys(k for r in rows for k in r) if k not in names and k not in TAIL]
    if rows and not any(metric in r for r in rows):
        return f"no plot: --metric {metric} is not a value of this job; its values: {', '.join(keys)}"
    return f"no plot: no row has a number for {metric}, or no option has two values"


def _plot(spec: CatalogEntry, config: SweepConfig, rows: list[dict[str, Any]], names: list[str],
          path: Path) -> Path | None:
    from mbctl.jobs.sweep_plots import plot_sweep

    return plot_sweep(rows, names, config.metric or spec.main_value, f"mbctl sweep {spec.name}", path)
