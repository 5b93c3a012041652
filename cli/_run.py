"""Run a job from the command line: the runner, the summary, the exit code.

The command modules import their jobs inside the command (``mbctl --help`` loads no engine), then
call :func:`execute`.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

if TYPE_CHECKING:
    from mbctl.jobs.runner import Job, RunRecord
    from mbctl.sim.video import VideoSpec

#: ``--output`` for every job: the run folder (default out/<command>).
OutputOpt = Annotated[
    Path | None, typer.Option("--output", help="Run folder (default out/<command>/); replaced by each run.")
]
#: ``--quiet``: no progress bar.
QuietOpt = Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar.")]
#: ``--video``: film the run headless into video.mp4 (simulating jobs).
VideoOpt = Annotated[
    bool, typer.Option("--video", help="Film the run headless into video.mp4 (30 frames per simulated s).")
]
#: ``--payload``: a hidden point mass on the plant (every simulating job).
PayloadOpt = Annotated[
    str | None,
    typer.Option("--payload", help="Plant only: a point mass KG@BODY[:X,Y,Z] fixed to BODY, offset in the "
                                   "body frame (m); the controller's model does not have it."),
]
#: ``--plant-error``: the plant's link masses off (every simulating job).
PlantErrorOpt = Annotated[
    float, typer.Option("--plant-error", help="Plant only: link masses and inertias off by PCT (%).")
]
#: ``--controller-model``: the controller's model from a file (every simulating job).
ControllerModelOpt = Annotated[
    str | None,
    typer.Option("--controller-model", help="The controller's model from this MJCF (e.g. identified.xml); "
                                            "the plant stays the robot's own. Same joints required."),
]
#: ``--video-size``: frame size of ``--video``.
VideoSizeOpt = Annotated[str, typer.Option("--video-size", help="Video frame size WIDTHxHEIGHT (px).")]


def video_spec(video: bool, size: str) -> VideoSpec | None:
    """The ``--video`` / ``--video-size`` options as a VideoSpec (None when not filming)."""
    from mbctl.sim.video import VideoSpec, parse_size

    width, height = parse_size(size)  # checked even without --video: a typo is an error
    return VideoSpec(width, height) if video else None


def execute(
    job: Job[Any], params: Any, output: Path | None, quiet: bool, video: VideoSpec | None = None
) -> RunRecord:
    """Run ``job``, print its summary (the interruption line on stderr) and exit with its code.

    Exit codes: 0 completed within bounds; 1 outside a bound, diverged or failed; 130 interrupted.
    Bad input and unusable output folders raise toolkit errors, which the entry point turns into
    exit 2.
    """
    from mbctl.jobs.runner import run_job

    record = run_job(job, params, output, quiet=quiet, video=video)
    typer.echo(record.summary(), err=record.status != "completed")
    if record.exit_code:
        raise typer.Exit(record.exit_code)
    return record
