"""Run a job from the command line: the runner, the summary, the exit code."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from mbctl.jobs.runner import Job, RunRecord, run_job

#: ``--output`` for every job: the run folder (default out/<command>).
OutputOpt = Annotated[
    Path | None, typer.Option("--output", help="Run folder (default out/<command>/); replaced by each run.")
]
#: ``--quiet``: no progress bar.
QuietOpt = Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar.")]


def execute(job: Job[Any], params: Any, output: Path | None, quiet: bool) -> RunRecord:
    """Run ``job``, print its summary (the interruption line on stderr) and exit with its code.

    Exit codes: 0 completed within bounds; 1 outside a bound, diverged or failed; 130 interrupted.
    Bad input and unusable output folders raise toolkit errors, which the entry point turns into
    exit 2.
    """
    record = run_job(job, params, output, quiet=quiet)
    typer.echo(record.summary(), err=record.status != "completed")
    if record.exit_code:
        raise typer.Exit(record.exit_code)
    return record
