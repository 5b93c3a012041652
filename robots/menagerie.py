"""Resolving third-party models from MuJoCo Menagerie, with SHA-256 verification.

Resolution order for a Menagerie model directory:

1. an explicit path given by the caller;
2. ``$MENAGERIE_ROOT/<name>``;
3. the ``mujoco-menagerie`` package, which downloads, hash-checks and caches the archive.

Where a ``MANIFEST.sha256`` (``sha256sum`` format) sits in the model directory, every file it
lists is checked; a file that differs raises :class:`ModelFileError` naming it.
"""

from __future__ import annotations

import functools
import hashlib
import os
from pathlib import Path

from mbctl.robots.exceptions import ModelFileError, ModelNotFoundError

MANIFEST_NAME = "MANIFEST.sha256"
MENAGERIE_ENV = "MENAGERIE_ROOT"


def sha256_file(path: Path) -> str:
    """Hex SHA-256 of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


def resolve_menagerie_dir(name: str, path: str | os.PathLike | None = None) -> Path:
    """The verified directory of Menagerie model ``name`` (e.g. "unitree_g1").

    Args:
        name: Menagerie directory name.
        path: An explicit model directory; overrides everything else.

    Raises:
        ModelNotFoundError: The model is not on this machine and cannot be downloaded.
        ModelFileError: A file fails the directory's SHA-256 manifest.
    """
    if path is not None:
        directory = Path(path).expanduser().resolve()
        if not directory.is_dir():
            raise ModelNotFoundError(f"Model directory {str(directory)!r} does not exist.")
    elif os.environ.get(MENAGERIE_ENV):
        root = Path(os.environ[MENAGERIE_ENV]).expanduser().resolve()
        directory = root / name
        if not directory.is_dir():
            raise ModelNotFoundError(
                f"{MENAGERIE_ENV}={root} has no {name!r} folder; point {MENAGERIE_ENV} at the "
                f"folder that contains {name}/ (a Menagerie checkout)."
            )
    else:
        directory = _from_package(name)
    verify_manifest(directory)
    return directory


def _from_package(name: str) -> Path:
    try:
        import mujoco_menagerie
    except ImportError as exc:  # pragma: no cover - it is a hard dependency
        raise ModelNotFoundError(
            f"mujoco-menagerie is not installed; `pip install mujoco-menagerie` or set "
            f"{MENAGERIE_ENV} to a folder containing {name}/."
        ) from exc
    try:
        return Path(mujoco_menagerie.get(name).path(progress=None))
    except mujoco_menagerie.ChecksumError as exc:
        raise ModelFileError(f"Downloaded archive for {name!r} failed its hash check: {exc}") from exc
    except (mujoco_menagerie.MenagerieError, OSError) as exc:
        raise ModelNotFoundError(
            f"Could not obtain Menagerie model {name!r} ({exc}). Offline? Set {MENAGERIE_ENV} to a "
            f"folder containing {name}/ (e.g. export {MENAGERIE_ENV}=/path/to/mujoco_menagerie), "
            f"or pass an explicit path."
        ) from exc


def verify_manifest(directory: Path) -> None:
    """Check every file listed in ``directory/MANIFEST.sha256``; no manifest means no check.

    Raises:
        ModelFileError: A listed file is missing or its SHA-256 differs (the file is named).
    """
    manifest = directory / MANIFEST_NAME
    if manifest.is_file():
        # Hashing ~36 MB of meshes takes ~0.1 s: the result is cached within a process, keyed
        # by the size and mtime of every file, so any change to a file is hashed again.
        signature = tuple(
            (str(p), st.st_size, st.st_mtime_ns)
            for p in sorted(directory.rglob("*"))
            if p.is_file() and (st := p.stat())
        )
        _verify_cached(str(directory), signature)


@functools.lru_cache(maxsize=16)
def _verify_cached(directory: str, _signature: tuple) -> None:
    root = Path(directory)
    for lineno, line in enumerate((root / MANIFEST_NAME).read_text().splitlines(), start=1):
        if not line.strip():
            continue
        try:
            expected, rel = line.split(maxsplit=1)
        except ValueError:
            raise ModelFileError(f"{root / MANIFEST_NAME}:{lineno} is not 'sha256  path'") from None
        rel = rel.strip().lstrip("*")
        file = root / rel
        if not file.is_file():
            raise ModelFileError(f"{file} is listed in {MANIFEST_NAME} but missing.")
        actual = sha256_file(file)
        if actual != expected.lower():
            raise ModelFileError(
                f"{file} fails its SHA-256 check: expected {expected}, got {actual}. "
                f"The model files were modified or corrupted; restore them."
            )
