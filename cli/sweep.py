"""CLI: ``mbctl sweep JOB --param NAME=V1,V2 ...`` — one job over a grid of values, on Dask."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer

from mbctl.cli._run import QuietOpt
from mbctl.jobs.choices import SWEEP_JOBS
from mbctl.limits import MAX_SWEEP_TASKS


def sweep(
    job: Annotated[str, typer.Argument(help=f"The job to sweep: {', '.join(SWEEP_JOBS)}.")],
    param: Annotated[
        list[str] | None,
        typer.Option("--param", help="NAME=V1,V2,... : the job's option (dashes as underscores, the "
                                     "option's units) and its values; ';' separates values holding "
                                     "commas; a glob expands to files (repeatable)."),
    ] = None,
    seeds: Annotated[
        int | None, typer.Option("--seeds", help="Run seeds 0..N-1 of each combination (jobs with --seed).")
    ] = None,
    workers: Annotated[int, typer.Option("--workers", help="Local worker processes, 1 thread each.")] = 2,
    scheduler: Annotated[
        str | None, typer.Option("--scheduler", help="Use this Dask scheduler (tcp://HOST:PORT).")
    ] = None,
    connect_timeout: Annotated[
        float, typer.Option("--connect-timeout", help="Seconds to wait for --scheduler to answer.")
    ] = 10.0,
    dashboard: Annotated[
        bool, typer.Option("--dashboard", help="Serve the Dask dashboard (local cluster, port 8787).")
    ] = False,
    resume: Annotated[
        bool, typer.Option("--resume", help="Keep the completed rows of DIR/sweep.csv; run the rest.")
    ] = False,
    metric: Annotated[
        str | None, typer.Option("--metric", help="Report value to plot (default: the job's main value).")
    ] = None,
    output: Annotated[
        Path | None,
        typer.Option("--output", help="Sweep folder (default out/sweep-JOB/): sweep.csv, sweep.json, "
                                      "sweep.png, runs/."),
    ] = None,
    quiet: QuietOpt = False,
    force: Annotated[
        bool, typer.Option("--force", help=f"Run a grid of more than {MAX_SWEEP_TASKS:,} tasks.")
    ] = False,
) -> None:
    """Run JOB for every combination of the values (times the seeds); exit 1 if a row did not pass.

    A row does not pass when its run failed, diverged or ended outside its bound; the summary
    says which rows and why, and prints the metric of every row.
    """
    from mbctl.jobs.catalog import parse_grid
    from mbctl.jobs.runner import Progress
    from mbctl.jobs.sweep import CSV_NAME, SweepConfig, run_sweep
    from mbctl.jobs.sweep_table import metric_table, summary_lines

    grid = parse_grid(job, param or [], seeds)
    folder = output or Path("out") / f"sweep-{job}"
    config = SweepConfig(job, grid, folder, workers, scheduler, dashboard, resume, metric, connect_timeout,
                         force)
    result = run_sweep(config, Progress(enabled=not quiet and sys.stdout.isatty()))
    lines = [f"{len(result.rows)} rows ({result.ran} run, {result.skipped} kept) in "
             f"{result.wall_time_s:.1f} s; {len(result.failures)} not completed",
             "wrote " + ", ".join(str(p) for p in result.files.values())]
    if result.earlier:
        lines.append(f"kept {len(result.earlier)} rows of an earlier grid in {CSV_NAME} (after this grid's)")
    if result.unsound:
        lines.append(f"{result.unsound} rows of the earlier {CSV_NAME} were torn or disagreed with their "
                     "run folder: dropped (this grid's ones ran again)")
    if result.note:
        lines.append(result.note)
    lines += summary_lines(result.rows) + metric_table(result.rows, list(grid), result.metric)
    if result.status == "interrupted":
        lines.insert(0, "interrupted: the remaining tasks were cancelled; --resume runs them")
    typer.echo("\n".join(lines), err=result.status != "completed")
    if result.exit_code:
        raise typer.Exit(result.exit_code)


def register(app: typer.Typer) -> None:
    """Add ``mbctl sweep`` to ``app``."""
    app.command("sweep")(sweep)
