"""The one job runner: output folder, streamed CSV, report with a status, plots, exit codes.

A job is a frozen parameter dataclass (validated in ``__post_init__``) and a ``prepare``
function. ``prepare(params)`` loads the robot and checks every name and value; it writes
nothing, so bad input fails before any work or file (exit 2). It returns the work: a function of
a :class:`RunContext` that streams rows, saves plots, fills ``ctx.values`` as results become
known and returns an :class:`Outcome`.

The runner owns the output folder (one run per folder):

- The folder is created and checked writable before ``prepare`` runs; an unusable path is an
  :class:`OutputError` (exit 2) naming it.
- A lock file ``.mbctl.lock`` (holding the pid) makes a second concurrent run into the same folder
  refuse with a message naming the other process; a lock left by a dead process is taken over.
- The files of an earlier run in the folder (those its ``report.json`` lists with their SHA-256
  and that still have it, the report itself and temporary files of dead processes) are removed
  before the new run writes anything, so no file of an earlier run survives beside a new one,
  and no other file is removed (see :func:`clear_previous_run`). A folder that holds another
  job's run is refused (:class:`OutputError`, exit 2), naming the folder and that job.
- ``report.json`` is written when the work starts (status ``running``) and again at the end in
  every case: ``completed``, ``uncommanded`` (the work ran to its end but its controller did not
  act on the plant, or too rarely to judge it: :meth:`RunContext.refuse_pass`, with the reason),
  ``interrupted`` (Ctrl-C or SIGTERM), ``diverged`` (the plant diverged) or ``failed`` (with the
  message), with the values known so far, the row count, the outputs and the plant's model and run
  sections.

Exit codes: 0 completed within bounds; 1 completed outside a bound, uncommanded, diverged or
failed; 2 bad input, usage or IO; 130 interrupted.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import asdict, dataclass, field, is_dataclass, replace
from pathlib import Path
from types import FrameType
from typing import Any, Generic, TypeVar

import numpy as np

from mbctl.exceptions import ToolkitError
from mbctl.jobs.exceptions import JobError as JobError
from mbctl.jobs.exceptions import OutputError as OutputError
from mbctl.jobs.progress import Progress as Progress
from mbctl.jobs.run_folder import LOCK_NAME as LOCK_NAME
from mbctl.jobs.run_folder import (
    REPORT_NAME,
    check_output_dir,
    check_output_names,
    clear_previous_run,
    folder_lock,
    output_hashes,
    refuse_another_jobs_run,
    refuse_link,
)
from mbctl.jobs.run_folder import check_output_file as check_output_file
from mbctl.sim.atomic import write_bytes_atomic, write_json_atomic
from mbctl.sim.csv_stream import FLUSH_INTERVAL_S
from mbctl.sim.exceptions import OutputPathError, SimulationDiverged
from mbctl.sim.recorder import MAX_REPLAY_SAMPLES, BoundedTrajectoryRecorder, CsvStream
from mbctl.sim.report import environment, model_section, run_section
from mbctl.sim.simulator import Simulator
from mbctl.sim.trajectory import MODEL_NAME, TRAJECTORY_NAME, TrajectoryRecorder
from mbctl.sim.video import Overlay, VideoRecorder, VideoSpec

P = TypeVar("P")

EXIT_OK = 0
EXIT_OUT_OF_BOUND = 1
EXIT_BAD_INPUT = 2
EXIT_INTERRUPTED = 130

VIDEO_NAME = "video.mp4"
#: Status of a run whose work ran to its end without its controller acting on the plant (or too
#: rarely to judge it): whatever the job's own verdict, not a pass (exit 1).
UNCOMMANDED = "uncommanded"


class InputFoundBad(JobError):  # noqa: N818 - bad input, found by the work (exit 2)
    """Bad input only the work can find (a log that is another run's): status ``failed``, exit 2."""


class Interrupted(BaseException):  # noqa: N818 - an interruption, like KeyboardInterrupt
    """Raised in the main thread when the process receives SIGTERM."""


@dataclass(frozen=True)
class Outcome:
    """What a job's work returns.

    Attributes:
        passed: The result is within its bound (robot stood, tracking bound met, check passed).
        summary: Human-readable lines with units, printed by the CLI.
        bound: What ``passed`` was judged against, for the report (e.g. "pelvis within 20 mm").
    """

    passed: bool = True
    summary: tuple[str, ...] = ()
    bound: str | None = None


@dataclass
class RunContext:
    """What a job's work writes through: the folder, the CSV, figures, values, report sections.

    Attributes:
        output_dir: The run folder.
        values: The job's results (units in the key names); filled as they become known, so an
            interrupted run still reports what it had.
        sections: Extra report sections (inputs, gains, reference …), JSON-serialisable.
        progress: The progress bar.
    """

    output_dir: Path
    job: str
    values: dict[str, Any] = field(default_factory=dict)
    sections: dict[str, Any] = field(default_factory=dict)
    progress: Progress = field(default_factory=Progress)
    files: dict[str, Path] = field(default_factory=dict)
    sim: Simulator | None = None
    csv: CsvStream | None = None
    video: VideoSpec | None = None
    uncommanded: str | None = None
    _streams: list[CsvStream] = field(default_factory=list)
    _recorders: list[TrajectoryRecorder | VideoRecorder] = field(default_factory=list)
    _values_at_end: list[Callable[[], object]] = field(default_factory=list)

    def values_at_end(self, fill: Callable[[], object]) -> None:
        """Have ``fill`` (which updates :attr:`values`) called once more if the work does not complete.

        For a job's per-cycle log: an interrupted, diverged or failed run's report gets the figures of
        every cycle it ran, computed once after the loop (the plant keeps the robot safe meanwhile)
        instead of refreshed during it, where a refresh over a long run's cycles would stall the loop.
        """
        self._values_at_end.append(fill)

    def fill_values_at_end(self) -> None:
        """Call the :meth:`values_at_end` functions; one that fails is named in ``values``, not raised."""
        for fill in self._values_at_end:
            try:
                fill()
            except Exception as exc:  # noqa: BLE001 - the report must still be written
                self.values.setdefault("values_at_end_error", f"{type(exc).__name__}: {exc}")

    def refuse_pass(self, reason: str) -> None:
        """Its controller did not act on the plant: whatever the outcome, status ``uncommanded`` (exit 1).

        The work goes on to its end (rows, values, plots kept); ``reason`` is the run's message.
        """
        self.uncommanded = reason

    def path(self, name: str, role: str | None = None) -> Path:
        """The path of output ``name`` in the run folder, registered under ``role`` (default name)."""
        path = self.output_dir / name
        self.files[role or name] = path
        return path

    def open_csv(self, header: Sequence[str], name: str | None = None, *,
                 flush_interval_s: float = FLUSH_INTERVAL_S) -> CsvStream:
        """Open the run's streamed CSV (``<job>.csv`` by default); the runner closes it.

        The first CSV opened is the run's main one: its row count and last ``time_s`` go in the
        report and the interruption message.

        Args:
            header: Column names (with units).
            name: File name in the run folder (default ``<job>.csv``).
            flush_interval_s: Longest wait [s] of a row before it is on disk; 0 writes each row
                through (for a log another process reads while the run goes on).
        """
        stream = CsvStream(self.path(name or csv_name(self.job), "csv" if not
                                     self._streams else name), header, flush_interval_s=flush_interval_s)
        self._streams.append(stream)
        if self.csv is None:
            self.csv = stream
        return stream

    def attach(
        self, sim: Simulator, *, contact_forces: bool = False, overlay: Overlay | None = None,
        frame_qpos: np.ndarray | None = None, frame_points_W: np.ndarray | None = None,
    ) -> Simulator:
        """Make ``sim`` the run's plant: report sections, trajectory for replay, video if filmed.

        Its model and run sections go in the report, its trajectory in ``trajectory.npz`` +
        ``model.xml`` (for replay; at most :data:`~mbctl.sim.recorder.MAX_REPLAY_SAMPLES` samples,
        evenly spaced, so a long run's memory stays bounded; the report's ``replay`` section says
        how many and how far apart) and, when the run is filmed, its frames in ``video.mp4``.

        Only the first simulator attached is recorded (``demo --compare`` runs several).

        Args:
            sim: The plant.
            contact_forces: Draw contact force arrows in the video.
            overlay: Adds markers to each video frame's scene (e.g. the reference path).
            frame_qpos: Plant configurations (k, nq) of the planned motion: a fixed robot's video
                camera frames them.
            frame_points_W: Points (m, 3) [m] in W the video camera frames too.
        """
        first = self.sim is None
        self.sim = sim
        if first:
            traj = BoundedTrajectoryRecorder(sim, self.output_dir, MAX_REPLAY_SAMPLES)
            self.files["model"], self.files["trajectory"] = traj.model_path, traj.path
            self._recorders.append(traj.attach())
            if self.video is not None:
                spec = replace(self.video, contact_forces=contact_forces or self.video.contact_forces)
                film = VideoRecorder(sim, self.path(VIDEO_NAME, "video"), spec, overlay, frame_qpos,
                                     frame_points_W)
                self._recorders.append(film.attach())
        return sim

    def save_figure(self, fig: Any, name: str) -> Path:
        """Save a matplotlib figure as PNG (atomically, 110 dpi) and close it."""
        path = self.path(name, name if self.files.get("plot") else "plot")
        write_bytes_atomic(path, lambda f: fig.savefig(f, format="png", dpi=110))
        from matplotlib import pyplot as plt

        plt.close(fig)
        return path

    def close_streams(self) -> None:
        """Close every CSV, the trajectory and the video (idempotent); the replay's sampling in the report."""
        for stream in self._streams:
            stream.close()
        for recorder in self._recorders:
            recorder.close()
            if isinstance(recorder, BoundedTrajectoryRecorder):
                self.sections["replay"] = {"samples": recorder.samples, "every_nth_update": recorder.stride,
                                           "updates": recorder.observed}

    @property
    def rows(self) -> int:
        """Rows in the main CSV so far."""
        return self.csv.rows if self.csv is not None else 0

    @property
    def last_time_s(self) -> float | None:
        """``time_s`` of the main CSV's last row, if it has that column and a row."""
        if self.csv is None or not self.csv.rows or "time_s" not in self.csv.header:
            return None
        return float(self.csv.last[self.csv.header.index("time_s")])


Work = Callable[[RunContext], Outcome]


@dataclass(frozen=True)
class Job(Generic[P]):
    """A job: its command name and how to prepare its work from its parameters.

    Attributes:
        name: The command name (``g1-stand``); files are named after it, the default folder is
            ``out/<name>``.
        prepare: Validates and loads from the parameters (writes nothing) and returns the work.
    """

    name: str
    prepare: Callable[[P], Work]


@dataclass(frozen=True)
class RunRecord:
    """The result of ``run_job``.

    Attributes:
        status: completed | uncommanded | interrupted | diverged | failed.
        exit_code: 0, 1, 2 (an output the work opened cannot be written safely, or
            :class:`InputFoundBad`) or 130 (see the module docstring).
        values: The job's values (partial unless completed).
        files: Written files by role (the report included).
        rows: Rows in the main CSV.
        last_time_s: ``time_s`` of the last row, or None.
        message: The error message for uncommanded, interrupted, diverged or failed runs.
        outcome: The work's Outcome when it completed.
    """

    status: str
    exit_code: int
    values: dict[str, Any]
    files: dict[str, Path]
    rows: int
    last_time_s: float | None
    message: str | None
    outcome: Outcome | None

    @property
    def report_path(self) -> Path:
        """The report JSON."""
        return self.files["report"]

    def summary(self) -> str:
        """What the CLI prints: the outcome's lines or the status, then the files."""
        if self.status == "interrupted":
            t = f"t={self.last_time_s:.3f} s" if self.last_time_s is not None else "the start"
            where = self.files.get("csv", self.report_path)
            return f"interrupted at {t}; wrote {self.rows} rows to {where}"
        if self.status == UNCOMMANDED:  # the job's lines describe a plant its controller did not drive
            return (f"NOT A PASS ({UNCOMMANDED}): {self.message}\nwrote {self.rows} rows; report "
                    f"{self.report_path}")
        if self.status != "completed":
            return f"{self.status}: {self.message}\nkept {self.rows} rows; report {self.report_path}"
        # the files first, the results (and the verdict) last, where a reader looks
        lines = ["wrote " + ", ".join(str(p) for p in self.files.values())]
        return "\n".join(lines + list(self.outcome.summary if self.outcome else ()))


def default_output(job: str) -> Path:
    """``out/<job>`` (relative to the working directory)."""
    return Path("out") / job


def csv_name(job: str) -> str:
    """The name of a job's main CSV: ``<job>.csv`` with dashes as underscores."""
    return f"{job.replace('-', '_')}.csv"


@contextlib.contextmanager
def sigterm_as_interrupt() -> Iterator[None]:
    """Turn SIGTERM into :class:`Interrupted` for the block (main thread only)."""
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: FrameType | None) -> None:
        raise Interrupted(f"signal {signum}")

    previous = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


@contextlib.contextmanager
def _signals_held() -> Iterator[None]:
    """Ignore SIGINT and SIGTERM for the block (main thread only): the final writes complete."""
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {sig: signal.signal(sig, signal.SIG_IGN) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def _jsonable(x: Any) -> Any:
    if is_dataclass(x) and not isinstance(x, type):
        return {k: _jsonable(v) for k, v in asdict(x).items()}
    if isinstance(x, Path):
        return str(x)
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    return x


def _report(ctx: RunContext, params: Any, status: str, message: str | None, outcome: Outcome | None,
            wall_s: float) -> dict[str, Any]:
    report: dict[str, Any] = {
        "job": ctx.job,
        "status": status,
        "message": message,
        "pid": os.getpid(),
        "command": sys.argv,
        "parameters": _jsonable(params),
        "environment": environment(),
    }
    if ctx.sim is not None:
        report["model"] = model_section(ctx.sim)
        report["run"] = run_section(ctx.sim)
    report["rows"] = ctx.rows
    report["last_time_s"] = ctx.last_time_s
    report["wall_time_s"] = wall_s
    if outcome is not None:
        report["passed"] = outcome.passed and status != UNCOMMANDED
        report["bound"] = outcome.bound
    report["values"] = _jsonable(ctx.values)
    report.update(_jsonable(ctx.sections))
    report["outputs"] = {role: p.name for role, p in ctx.files.items() if role != "report"}
    if status != "running":  # what the next run into this folder may remove, and nothing else
        report["output_sha256"] = output_hashes(ctx.output_dir, {
            role: p for role, p in ctx.files.items() if role != "report"})
    return report


def run_job(
    job: Job[P],
    params: P,
    output_dir: Path | None = None,
    *,
    quiet: bool = True,
    video: VideoSpec | None = None,
) -> RunRecord:
    """Run ``job`` with ``params`` into ``output_dir`` (default ``out/<job>``).

    Args:
        job: The job.
        params: Its parameters (a frozen dataclass, validated on construction).
        output_dir: The run folder.
        quiet: No progress bar (the bar also needs stdout to be a terminal).
        video: Film the run's plant into ``video.mp4`` (headless), or None.

    Returns:
        The RunRecord (status, exit code, values, files).

    Raises:
        OutputError: The folder is not usable or another run holds it, or a symbolic link sits at
            the job's CSV path (nothing written).
        ToolkitError: ``prepare`` found bad input (nothing written).
        BaseException: A programming error in the work is re-raised after the report is written
            (status ``failed``).
    """
    folder = check_output_dir(Path(output_dir) if output_dir is not None else default_output(job.name))
    check_output_names(folder, [REPORT_NAME, TRAJECTORY_NAME, MODEL_NAME, csv_name(job.name),
                                *([VIDEO_NAME] if video is not None else [])])
    refuse_link(folder / csv_name(job.name))  # the streamed CSV is opened in place: never via a link
    refuse_another_jobs_run(folder, job.name)  # a run replaces its own job's run, never another's
    work = job.prepare(params)
    progress = Progress(enabled=not quiet and sys.stdout.isatty())
    ctx = RunContext(folder, job.name, progress=progress, video=video)
    report_path = folder / REPORT_NAME
    with folder_lock(folder):
        clear_previous_run(folder)
        write_json_atomic(report_path, _report(ctx, params, "running", None, None, 0.0))
        wall0 = time.perf_counter()
        status, message, outcome, code = "failed", None, None, EXIT_OUT_OF_BOUND
        bug: BaseException | None = None
        try:
            with sigterm_as_interrupt():
                outcome = work(ctx)
            status = "completed"
            code = EXIT_OK if outcome.passed else EXIT_OUT_OF_BOUND
            if ctx.uncommanded is not None:
                status, message, code = UNCOMMANDED, ctx.uncommanded, EXIT_OUT_OF_BOUND
        except (KeyboardInterrupt, Interrupted):
            status, message, code = "interrupted", "interrupted by the user (Ctrl-C or SIGTERM)", 130
        except SimulationDiverged as exc:
            status, message = "diverged", str(exc)
        except (OutputPathError, InputFoundBad) as exc:  # an unsafe output, or input bad after all
            status, message, code = "failed", str(exc), EXIT_BAD_INPUT
        except ToolkitError as exc:
            status, message = "failed", str(exc)
        except BaseException as exc:  # a bug: report it, then let the traceback show
            status, message, bug = "failed", f"{type(exc).__name__}: {exc}", exc
        finally:
            with _signals_held():  # a second Ctrl-C must not cut the report short
                progress.stop()
                if status != "completed":
                    ctx.fill_values_at_end()
                ctx.close_streams()
                ctx.files["report"] = write_json_atomic(
                    report_path, _report(ctx, params, status, message, outcome, time.perf_counter() - wall0))
    if bug is not None:
        raise bug
    return RunRecord(status, code, ctx.values, dict(ctx.files), ctx.rows, ctx.last_time_s, message,
                     outcome)
