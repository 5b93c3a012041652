"""Atomic file output: write to a temporary file beside the target, fsync, then rename.

A reader never sees a torn file: either the previous file (or none) or the complete new one.
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path
from typing import IO, Any


class AtomicFile:
    """A text file that appears at ``path`` only when closed (``os.replace``).

    Use as a context manager. Whatever was written is published on exit, also when the block
    raised (so a recording keeps every complete row written before the error); call
    ``discard()`` to publish nothing.
    """

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{self.path.name}.", suffix=".tmp", dir=self.path.parent)
        self._tmp = Path(tmp)
        self.file: IO[str] = os.fdopen(fd, "w", newline="")
        self.closed = False

    def close(self) -> Path:
        """Flush, fsync and rename into place; returns the final path."""
        if not self.closed:
            self.file.flush()
            os.fsync(self.file.fileno())
            self.file.close()
            os.replace(self._tmp, self.path)
            self.closed = True
        return self.path

    def discard(self) -> None:
        """Drop the temporary file without publishing it."""
        if not self.closed:
            self.file.close()
            self._tmp.unlink(missing_ok=True)
            self.closed = True

    def __enter__(self) -> AtomicFile:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def write_text_atomic(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` to ``path`` atomically."""
    with AtomicFile(path) as f:
        f.file.write(text)
    return Path(path)


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
