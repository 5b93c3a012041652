"""Where a sweep runs: a local Dask cluster, or an existing scheduler checked before it is used.

A local cluster has ``workers`` processes of one thread each, started quietly. An existing
scheduler is given by its address: the address is parsed (a malformed one is bad input) and the
scheduler must answer Dask's handshake within a timeout, since Dask's own ``Client`` can wait
minutes on a port that accepts the connection but never speaks Dask (an HTTP server).
"""

from __future__ import annotations

import contextlib
import logging
import signal
import threading
import warnings
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

from mbctl.jobs.catalog import SweepInputError
from mbctl.jobs.exceptions import JobError

if TYPE_CHECKING:
    from mbctl.jobs.sweep import SweepConfig

INSTALL_HINT = "pip install 'mbctl[sweep]'"
NO_DASK = f"mbctl sweep runs on Dask, which is not installed: {INSTALL_HINT}"


class SweepSetupError(JobError):
    """Dask is missing, or the cluster cannot be started or reached."""


@contextlib.contextmanager
def _sigint_ignored() -> Iterator[None]:
    """Ignore SIGINT for the block (main thread only); processes started in it keep ignoring it."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def local_cluster(workers: int, dashboard: bool = False) -> Any:
    """A LocalCluster of ``workers`` processes with one thread each, started quietly.

    The workers ignore SIGINT (Ctrl-C reaches the sweep, which cancels and closes them). Without
    the dashboard the workers' statistical profiler, which only the dashboard shows, is off: it
    sampled every 10 ms and cost ~3 % of a task's CPU time.
    """
    import dask
    from dask.distributed import LocalCluster

    with _sigint_ignored(), dask.config.set({"distributed.worker.profile.enabled": dashboard}), \
            warnings.catch_warnings():
        # Without the dashboard the scheduler still serves /health on 8787, or on a free port when
        # 8787 is taken (another sweep): that fallback is not worth a warning.
        warnings.filterwarnings("ignore", message=".*already in use", category=UserWarning)
        return LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                            dashboard_address=":8787" if dashboard else None, silence_logs=logging.ERROR)


#: Dask comm schemes a scheduler can listen on (``inproc`` is within one process only).
SCHEDULER_SCHEMES = ("tcp", "tls", "ws", "wss", "ucx")


def parse_scheduler(address: str) -> str:
    """The scheduler address as ``scheme://host:port``; SweepInputError naming it if malformed.

    Raises:
        SweepInputError: No port, a port outside 1-65535, no host, or a scheme Dask cannot
            reach a scheduler by (``http://`` is the dashboard's, not the scheduler's).
    """
    from distributed.comm.addressing import parse_address, parse_host_port, unparse_address

    form = ("give tcp://HOST:PORT, e.g. tcp://127.0.0.1:8786 (the port the scheduler prints, not the "
            "dashboard's)")
    try:
        scheme, location = parse_address(address.strip(), strict=False)
        host, port = parse_host_port(location)
    except ValueError as exc:
        raise SweepInputError(f"--scheduler {address!r} is not a scheduler address ({exc}); {form}") from None
    if scheme not in SCHEDULER_SCHEMES:
        raise SweepInputError(f"--scheduler {address!r}: Dask reaches a scheduler by "
                              f"{', '.join(SCHEDULER_SCHEMES)}, not {scheme}://; {form}")
    if not host or not 0 < int(port) < 65536:
        raise SweepInputError(f"--scheduler {address!r} needs a host and a port in 1-65535; {form}")
    return unparse_address(scheme, location)


def check_scheduler(address: str, timeout_s: float) -> None:
    """Ask ``address`` who it is; SweepSetupError unless a Dask scheduler answers within ``timeout_s``.

    Dask's own ``Client(address, timeout=...)`` can wait minutes on a port that accepts the
    connection but never speaks Dask's protocol (an HTTP server); this handshake is bounded.
    """
    import asyncio

    from distributed.comm import connect

    async def identity() -> Any:
        comm = await connect(address, timeout=timeout_s)
        try:
            await comm.write({"op": "identity"})
            return await comm.read()
        finally:
            comm.abort()

    try:
        answer = asyncio.run(asyncio.wait_for(identity(), timeout_s))
    except (OSError, asyncio.TimeoutError, ValueError, TypeError) as exc:
        why = f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__
        raise SweepSetupError(
            f"no Dask scheduler answered at {address} within {timeout_s:g} s ({why}); check that "
            "`dask scheduler` runs there and that this is its address (not the dashboard's), or "
            "raise --connect-timeout") from None
    kind = answer.get("type") if isinstance(answer, dict) else None
    if kind != "Scheduler":
        raise SweepSetupError(f"{address} answers, but as a Dask {kind or 'peer of unknown kind'}, not a "
                              "scheduler: give the scheduler's address")


@contextlib.contextmanager
def open_client(config: SweepConfig) -> Iterator[tuple[Any, dict[str, Any]]]:
    """A Dask client on a new local cluster, or on ``config.scheduler``; closed after the block.

    Yields:
        The client and the cluster section of ``sweep.json`` (address, workers, threads).

    Raises:
        SweepInputError: The scheduler address is malformed.
        SweepSetupError: Dask is not installed, or no scheduler answers at the address within
            ``config.connect_timeout_s``.
    """
    try:
        from dask.distributed import Client
    except ImportError:
        raise SweepSetupError(NO_DASK) from None
    cluster = None
    try:
        if config.scheduler is not None:
            address = parse_scheduler(config.scheduler)
            check_scheduler(address, config.connect_timeout_s)
            client = Client(address, timeout=config.connect_timeout_s)
        else:
            cluster = local_cluster(config.workers, config.dashboard)
            client = Client(cluster)
    except OSError as exc:
        if cluster is not None:
            cluster.close()
        where = config.scheduler or "a local cluster"
        raise SweepSetupError(f"cannot start or reach {where}: {exc}") from None
    try:
        section = cluster_section(client)
        section.update(local=cluster is not None,
                       dashboard=client.dashboard_link if config.dashboard and cluster is not None else None)
        yield client, section
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def cluster_section(client: Any) -> dict[str, Any]:
    """The cluster section of ``sweep.json``: address, worker and thread counts."""
    workers = client.scheduler_info().get("workers", {})
    return {"address": client.scheduler.address, "local": False, "workers": len(workers),
            "threads": sum(w.get("nthreads", 0) for w in workers.values()), "dashboard": None}
