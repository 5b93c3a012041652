"""The run folder: created and proved writable, locked by one run, cleared of the previous run's files.

No output follows a symbolic link (see :mod:`mbctl.sim.atomic`); a folder's previous run loses
only the files it made and recorded with their SHA-256 in its report (``output_sha256``), so a
forged or stale report cannot make a run delete a user's file.
"""

from __future__ import annotations

import contextlib
import os
import stat
import tempfile
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from mbctl.jobs.exceptions import OutputError
from mbctl.robots.menagerie import sha256_file
from mbctl.sim.atomic import FILE_MODE, read_text_nofollow

REPORT_NAME = "report.json"
LOCK_NAME = ".mbctl.lock"


def check_output_dir(path: Path) -> Path:
    """Create ``path`` and prove it writable; OutputError naming it otherwise (nothing else written)."""
    path = Path(path)
    try:
        if path.exists() and not path.is_dir():
            raise OutputError(f"output {path} exists and is not a directory; choose a folder")
        path.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=".mbctl-write-test.", dir=path)  # O_EXCL: no link followed
        os.close(fd)
        os.unlink(probe)
    except OutputError:
        raise
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        raise OutputError(f"cannot write to output folder {path}: {reason}; choose another "
                          "--output") from None
    return path


def check_output_names(folder: Path, names: Sequence[str]) -> None:
    """OutputError if one of the files a run will write is a directory in ``folder`` (before the run)."""
    for name in names:
        path = folder / name
        if path.is_dir() and not path.is_symlink():  # a link is replaced, never followed
            raise OutputError(f"{path} is a directory where this run writes a file; remove it or "
                              "choose another --output")


def refuse_link(path: Path) -> None:
    """OutputError if ``path`` is a symbolic link: mbctl writes only into what it creates."""
    if Path(path).is_symlink():
        raise OutputError(f"{path} is a symbolic link; mbctl never writes through one (it could "
                          "overwrite a file elsewhere): remove the link or choose another --output")


def check_output_file(path: Path) -> Path:
    """Check that file ``path`` can be created (its folder made and writable) before any work."""
    check_output_dir(Path(path).parent)
    if Path(path).is_dir():
        raise OutputError(f"{path} is a directory; give a file name")
    return Path(path)


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


@contextlib.contextmanager
def folder_lock(path: Path) -> Iterator[None]:
    """Hold ``path/.mbctl.lock`` for the block; OutputError if a live process holds it."""
    lock = path / LOCK_NAME
    for _ in range(2):
        try:
            fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, FILE_MODE)
        except FileExistsError:
            try:
                pid = int(lock.read_text().strip() or "0")
            except (OSError, ValueError):
                pid = 0
            if pid and pid != os.getpid() and _pid_alive(pid):
                raise OutputError(
                    f"another mbctl run (pid {pid}) is writing to {path}; wait for it or choose "
                    "another --output"
                ) from None
            lock.unlink(missing_ok=True)  # left by a process that is gone
            continue
        with os.fdopen(fd, "w") as f:
            f.write(str(os.getpid()))
        break
    try:
        yield
    finally:
        lock.unlink(missing_ok=True)


def output_hashes(folder: Path, files: dict[str, Path]) -> dict[str, str]:
    """SHA-256 of each output in ``files`` that is a plain file in ``folder``, by file name."""
    hashes = {}
    for path in files.values():
        if path.parent == folder and stat.S_ISREG(_lstat_mode(path)):
            hashes[path.name] = sha256_file(path)
    return hashes


def _lstat_mode(path: Path) -> int:
    try:
        return os.lstat(path).st_mode
    except OSError:
        return 0


def _made_by_the_run(folder: Path, name: Any, digest: Any) -> bool:
    """Whether ``name`` is a plain file directly in ``folder`` (no link) whose SHA-256 is ``digest``."""
    if not isinstance(name, str) or not isinstance(digest, str) or name in ("", ".", "..") \
            or name != Path(name).name or "\0" in name:
        return False
    path = folder / name
    return stat.S_ISREG(_lstat_mode(path)) and sha256_file(path) == digest.lower()


def _previous_report(path: Path) -> dict[str, Any]:
    """The folder's ``report.json`` as a dict ({} when absent, a link, or not a report)."""
    import json

    report = path / REPORT_NAME
    if report.is_symlink() or not report.is_file():
        return {}
    try:
        data = json.loads(read_text_nofollow(report))
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def refuse_another_jobs_run(path: Path, job: str) -> None:
    """OutputError if ``path`` holds a run of another job (its ``report.json`` names that job).

    A run replaces the previous run of its own job in its folder; the run of another job (an
    excitation log that ``mbctl identify RUN --output RUN`` would read and then delete) is kept,
    and the new run refused before anything is written.
    """
    data = _previous_report(path)
    other = data.get("job")
    if not isinstance(other, str) or not other or other == job:
        return
    hashes = data.get("output_sha256")
    files = sorted(hashes) if isinstance(hashes, dict) else []
    held = f" ({', '.join(files[:6])}{' ...' if len(files) > 6 else ''})" if files else ""
    raise OutputError(
        f"output folder {path} holds a run of `mbctl {other}` (its {REPORT_NAME} says job {other!r}){held}; "
        f"`mbctl {job}` would replace that run's files: choose another --output (a folder of its own, "
        f"e.g. out/{job}), or delete that run's files first")


def clear_previous_run(path: Path) -> None:
    """Remove the previous run's outputs, its report and dead temp files.

    Only files the previous run made are removed: those its report lists in ``output_sha256``
    that are plain files in the folder (not links) with that SHA-256. A forged or stale report
    cannot make a run delete a user's file; a file edited since the run is left alone. A report
    that is a symbolic link is removed without being read.
    """
    report = path / REPORT_NAME
    if report.exists() or report.is_symlink():
        hashes = _previous_report(path).get("output_sha256")
        for name, digest in hashes.items() if isinstance(hashes, dict) else ():
            if _made_by_the_run(path, name, digest):
                (path / name).unlink()
        report.unlink()
    for tmp in path.glob(".*.tmp"):
        tmp.unlink(missing_ok=True)  # under the lock, every temp file is a dead process's
