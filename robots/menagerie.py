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
#: How long [s] the download host may take to accept a connection before mbctl calls it offline.
#: mujoco-menagerie's own download tries 3 times with a 60 s timeout and 1 + 2 s of back-off, so
#: an offline machine waited 8-16 s (or minutes behind a firewall that drops packets) for the error.
CONNECT_TIMEOUT_S = 2.0


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
            raise ModelNotFoundError(
                f"Model directory {str(directory)!r} does not exist; give the folder that holds "
                f"the model's XML files (e.g. /path/to/mujoco_menagerie/{name})."
            )
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


def how_to_provide(name: str) -> str:
    """The forms that give a Menagerie model without a download (for error messages)."""
    return (
        f"set {MENAGERIE_ENV} to a folder that contains {name}/ (export {MENAGERIE_ENV}=/path/to/"
        f"mujoco_menagerie), or pass the model directory explicitly (`--model-dir /path/to/{name}` "
        f"on the command line, `load_robot(..., model_dir=\"/path/to/{name}\")` in Python)"
    )


def _from_package(name: str) -> Path:
    """The model from the mujoco-menagerie package: its cache first, a download only if absent."""
    import sys

    try:
        import mujoco_menagerie
    except ImportError:  # pragma: no cover - it is a hard dependency
        raise ModelNotFoundError(
            f"mujoco-menagerie is not installed and {MENAGERIE_ENV} is unset; "
            f"`pip install mujoco-menagerie` or {how_to_provide(name)}."
        ) from None
    try:
        entry = mujoco_menagerie.get(name)
        cache = mujoco_menagerie.Cache()
        if not cache.is_cached(entry):
            unreachable = _unreachable(cache.base_url)
            if unreachable:
                raise ModelNotFoundError(
                    f"Menagerie model {name!r} is not on this machine and cannot be downloaded: "
                    f"{unreachable}. Offline? {how_to_provide(name)[0].upper()}{how_to_provide(name)[1:]}.")
            size_mb = entry.download_size / 1e6 if entry.download_size else float("nan")
            print(f"mbctl: {name} is not cached; downloading {size_mb:.0f} MB "
                  f"(offline? set {MENAGERIE_ENV} or pass --model-dir)", file=sys.stderr)
        return Path(entry.path(cache, progress=None))
    except mujoco_menagerie.ChecksumError as exc:
        raise ModelFileError(f"Downloaded archive for {name!r} failed its hash check: {exc}") from None
    except (mujoco_menagerie.MenagerieError, OSError) as exc:
        raise ModelNotFoundError(
            f"Menagerie model {name!r} is not on this machine and could not be downloaded "
            f"({type(exc).__name__}: {exc}). Offline? {how_to_provide(name)[0].upper()}"
            f"{how_to_provide(name)[1:]}."
        ) from None


def _unreachable(url: str, timeout_s: float = CONNECT_TIMEOUT_S) -> str | None:
    """Why ``url``'s host cannot be connected to within ``timeout_s`` (name lookup included), or None.

    The lookup (``getaddrinfo``) takes no timeout, so the connection is tried in a daemon thread
    that is abandoned after ``timeout_s``. Non-network URLs (``file:``) pass.
    """
    import socket
    import threading
    from urllib.parse import urlsplit

    parts = urlsplit(url)
    if parts.scheme not in ("http", "https") or not parts.hostname:
        return None
    host, port = parts.hostname, parts.port or (443 if parts.scheme == "https" else 80)
    outcome: list[str | None] = []

    def connect() -> None:
        try:
            socket.create_connection((host, port), timeout=timeout_s).close()
            outcome.append(None)
        except OSError as exc:
            outcome.append(f"{type(exc).__name__}: {exc.strerror or exc}")

    thread = threading.Thread(target=connect, name="mbctl-menagerie-probe", daemon=True)
    thread.start()
    thread.join(timeout_s)
    if not outcome:
        return f"no connection to {host}:{port} within {timeout_s:g} s"
    return None if outcome[0] is None else f"cannot connect to {host}:{port} ({outcome[0]})"


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
