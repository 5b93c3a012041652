"""The CPU cores a run may use (``mbctl --cpus 0``): parsed, checked against the machine, applied.

A controller and a plant on one machine (a DDS job beside ``mbctl serve g1``) share its cores; each
on a core of its own misses fewer deadlines (the walking job's figures: docs/api/walking.rst), as a
robot's own computer runs its controller. The process's affinity is set (``os.sched_setaffinity``,
Linux) before it starts a thread, so every thread started later (DDS, the CSV writer, the workers
of a local sweep) inherits it. ``taskset -c`` does the same from outside; this option is the same
on every command and recorded in the run's report (``environment.cpus``).
"""

from __future__ import annotations

import os

from mbctl.jobs.exceptions import JobError

#: What ``--cpus`` takes, for messages.
CPUS_FORM = "core numbers and ranges, e.g. 0 or 0,2 or 1-3"


class CpuSetError(JobError, ValueError):
    """A ``--cpus`` value that is malformed, names a core this process cannot use, or an OS without it."""


def available_cpus() -> frozenset[int]:
    """The cores this process may run on now (all of them on an OS without affinities)."""
    if hasattr(os, "sched_getaffinity"):
        return frozenset(os.sched_getaffinity(0))
    return frozenset(range(os.cpu_count() or 1))


def parse_cpus(text: str) -> frozenset[int]:
    """Cores from ``"0"``, ``"0,2"``, ``"1-3"`` or a mix (``"0,2-3"``); spaces allowed.

    Raises:
        CpuSetError: Empty, not numbers, a negative core or a range whose end is before its start.
    """
    cores: set[int] = set()
    for part in text.split(","):
        part = part.strip()
        first, dash, last = part.partition("-")
        try:
            lo = int(first)
            hi = int(last) if dash else lo
        except ValueError:
            raise CpuSetError(f"--cpus {text!r}: {part!r} is not a core number or a range A-B; "
                              f"expected {CPUS_FORM}") from None
        if lo < 0 or hi < lo:
            raise CpuSetError(f"--cpus {text!r}: {part!r} is not a range of cores from 0 up; "
                              f"expected {CPUS_FORM}")
        cores.update(range(lo, hi + 1))
    return frozenset(cores)


def pin_process(text: str) -> tuple[int, ...]:
    """Run this process (and every thread it starts from now on) on the cores ``text`` names.

    Returns:
        The cores, sorted.

    Raises:
        CpuSetError: ``text`` is malformed (:func:`parse_cpus`), names a core this process may not
            use (the available ones are named), or the OS sets no affinities (e.g. macOS).
    """
    cores = parse_cpus(text)
    if not hasattr(os, "sched_setaffinity"):
        raise CpuSetError(f"--cpus {text!r}: this OS does not let a process choose its cores; run without "
                          "--cpus")
    available = available_cpus()
    missing = sorted(cores - available)
    if missing:
        raise CpuSetError(f"--cpus {text!r}: core(s) {', '.join(map(str, missing))} not available to this "
                          f"process; it may use {', '.join(map(str, sorted(available)))}")
    os.sched_setaffinity(0, cores)
    return tuple(sorted(cores))
