"""A DDS domain no other process on this machine is using: reserved by a lock file, not guessed.

Two processes that each derive a domain from their pid (test runs side by side, a benchmark next
to the tests) can land on the same id, and their participants would then talk to each other. The
reservation takes an exclusive, non-blocking ``flock`` on ``/tmp/mbctl-dds-<domain>.lock`` and
moves on to the next domain while one is held; the lock lives as long as the reservation (and
ends with the process if it dies). Only processes that reserve this way see each other: a domain
given by hand (``--domain``) is not checked. The lock files stay in ``/tmp`` (removing them would
race with a process about to lock them).

``/tmp`` is everyone's: a lock file is opened with ``O_NOFOLLOW`` (a symbolic link planted at its
path, dangling or not, is refused with :class:`ChannelError` naming it, never followed: creating
through it would make a file wherever it points), ``O_NONBLOCK`` (a FIFO planted there cannot hang
the open) and ``O_CLOEXEC``, and must be a regular file.
"""

from __future__ import annotations

import itertools
import os
import stat
from collections.abc import Iterator
from contextlib import contextmanager

from mbctl.unitree.channel import MAX_DOMAIN, check_domain
from mbctl.unitree.exceptions import ChannelError

#: Where the lock files live: one directory for every process on the machine (not $TMPDIR).
LOCK_DIR = "/tmp"

_calls = itertools.count()


def lock_path(domain: int) -> str:
    """The lock file of ``domain``: ``/tmp/mbctl-dds-<domain>.lock``."""
    return os.path.join(LOCK_DIR, f"mbctl-dds-{domain}.lock")


#: How a lock file is opened: never through a symbolic link, never blocking, not inherited.
_FLAGS = os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC


def _open(path: str) -> int:
    """A read-only descriptor on the regular file ``path``, created if missing (flock needs no write access).

    Raises:
        ChannelError: ``path`` is a symbolic link or not a regular file (planted in /tmp).
        OSError: Another reason it cannot be opened.
    """
    try:
        try:
            fd = os.open(path, _FLAGS)
        except FileNotFoundError:
            try:
                fd = os.open(path, _FLAGS | os.O_CREAT, 0o666)
            except PermissionError:  # another user made it meanwhile (fs.protected_regular refuses O_CREAT)
                fd = os.open(path, _FLAGS)
    except OSError as exc:
        if os.path.islink(path):  # O_NOFOLLOW's ELOOP: a link, dangling or not
            raise ChannelError(
                f"the DDS domain lock {path!r} is a symbolic link (to {os.readlink(path)!r}); refusing to "
                "follow it (someone may have planted it to make a file elsewhere): remove it if it is "
                "not yours") from None
        raise exc
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        os.close(fd)
        raise ChannelError(f"the DDS domain lock {path!r} is not a regular file; refusing to use it "
                           "(remove it if it is not yours)")
    return fd


def _try_lock(domain: int) -> int | None:
    """The descriptor holding ``domain``'s lock, or None if another holder has it (or it cannot open)."""
    import fcntl  # POSIX only; imported here so the module imports everywhere

    try:
        fd = _open(lock_path(domain))
    except OSError:  # ChannelError (a link, not a file) is not one: it stops the reservation
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        return None
    return fd


@contextmanager
def reserve_domain(first: int | None = None) -> Iterator[int]:
    """Reserve a DDS domain in 1..232 for the block; yields its id.

    Args:
        first: The domain tried first (then the next ones, wrapping round). Default: derived from
            the pid and a per-process counter, so the reservations of one process spread out.

    Raises:
        ChannelError: ``first`` is not a domain id in 1..232, every domain is held, or a lock file
            is a symbolic link or not a regular file.
    """
    if first is None:
        first = 1 + (os.getpid() * 37 + next(_calls)) % MAX_DOMAIN
    elif check_domain(first) == 0:
        raise ChannelError("reserve_domain hands out domains 1..232 (0 is DDS's default domain)")
    for i in range(MAX_DOMAIN):
        domain = 1 + (first - 1 + i) % MAX_DOMAIN
        fd = _try_lock(domain)
        if fd is None:
            continue
        try:
            yield domain
        finally:
            os.close(fd)  # closing the only descriptor releases the lock
        return
    raise ChannelError(f"every DDS domain 1..{MAX_DOMAIN} is reserved by another process "
                       f"(lock files {lock_path(1)} ...)")
