"""Atomic file output: write to a temporary file beside the target, fsync, then rename.

A reader never sees a torn file: either the previous file (or none) or the complete new one.
No output follows a symbolic link: a link planted at the final name is replaced by the rename,
and the temporary file is created with ``O_EXCL`` and reopened with ``O_NOFOLLOW``.
"""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

#: Mode of every published file (mkstemp creates 0600): owner rw, group and others read.
FILE_MODE = 0o644


class BesideFile:
    """A temporary file beside ``path`` for a writer that opens files by name (ffmpeg).

    ``publish()`` renames it to ``path``; ``discard()`` removes it. A symbolic link at ``path`` is
    replaced, never followed. The temporary name is unique per process (``mkstemp``, ``O_EXCL``)
    and ends in ``.tmp``, so the job runner removes it if the process dies.
    """

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{self.path.name}.", suffix=".tmp", dir=self.path.parent)
        os.close(fd)
        self.tmp = Path(tmp)
        self.done = False

    def open(self, mode: str = "wb", **kwargs: Any) -> IO[Any]:
        """Open the temporary file for writing (never through a link swapped in for it)."""
        return os.fdopen(os.open(self.tmp, os.O_WRONLY | os.O_TRUNC | os.O_NOFOLLOW), mode, **kwargs)

    def publish(self) -> Path:
        """Make the file readable by all (mode 0644) and rename it to ``path`` (idempotent)."""
        if not self.done:
            os.chmod(self.tmp, FILE_MODE)
            os.replace(self.tmp, self.path)
            self.done = True
        return self.path

    def discard(self) -> None:
        """Remove the temporary file without publishing it."""
        if not self.done:
            self.tmp.unlink(missing_ok=True)
            self.done = True


class AtomicFile:
    """A text file that appears at ``path`` only when closed (``os.replace``).

    Use as a context manager: the file is published when the block completes and discarded when
    it raises (KeyboardInterrupt included), so a half-written file never appears under the final
    name. The temporary name is unique per process (``mkstemp``). Streams that must keep their
    rows across an interruption use :class:`mbctl.sim.recorder.CsvStream` instead.
    """

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)
        self._out = BesideFile(self.path)
        self.file: IO[str] = self._out.open("w", newline="")
        self.closed = False

    def close(self) -> Path:
        """Flush, fsync and rename into place; returns the final path."""
        if not self.closed:
            self.file.flush()
            os.fsync(self.file.fileno())
            self.file.close()
            self._out.publish()
            self.closed = True
        return self.path

    def discard(self) -> None:
        """Drop the temporary file without publishing it."""
        if not self.closed:
            self.file.close()
            self._out.discard()
            self.closed = True

    def __enter__(self) -> AtomicFile:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, *exc: object) -> None:
        if exc_type is None:
            self.close()
        else:
            self.discard()


def write_text_atomic(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` to ``path`` atomically."""
    with AtomicFile(path) as f:
        f.file.write(text)
    return Path(path)


def write_bytes_atomic(path: str | os.PathLike, write: Callable[[IO[bytes]], None]) -> Path:
    """Publish what ``write(binary_file)`` writes at ``path`` atomically (figures, archives).

    The temporary file is unique per process and removed if ``write`` raises.
    """
    out = BesideFile(path)
    try:
        with out.open("wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        return out.publish()
    finally:
        out.discard()


def write_json_atomic(path: str | os.PathLike, data: Any) -> Path:
    """Write ``data`` as indented JSON to ``path`` atomically (NaN/inf written as null)."""
    return write_text_atomic(path, json.dumps(_finite(data), indent=2, sort_keys=False) + "\n")


def _finite(x: Any) -> Any:
    if isinstance(x, float):
        return x if x == x and abs(x) != float("inf") else None
    if isinstance(x, dict):
        return {str(k): _finite(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_finite(v) for v in x]
    if hasattr(x, "tolist"):
        return _finite(x.tolist())
    return x


def read_text_nofollow(path: str | os.PathLike) -> str:
    """The text of ``path``, refusing a symbolic link in its place (OSError ELOOP).

    For files a run reads back from its own folder (an earlier report): a link planted there
    must not make mbctl read, then act on, a file elsewhere.
    """
    fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW)
    with os.fdopen(fd, encoding="utf-8") as f:
        return f.read()
