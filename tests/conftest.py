"""Shared fixtures. The G1 runs in CI: it skips only when absent and CI is unset."""

from __future__ import annotations

import importlib
import os
import shlex
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from typing import Any

import pytest
from hypothesis import settings

from mbctl.gl import VideoError, choose_gl_backend

# MuJoCo reads MUJOCO_GL when first imported: pick the headless backend (EGL, then OSMesa) first.
try:
    GL_BACKEND: str | None = choose_gl_backend()
except VideoError:  # the rendering tests fail with the message; the rest run
    GL_BACKEND = None

from mbctl.robots import ModelNotFoundError, Robot, load_robot  # noqa: E402 - after the GL choice
from mbctl.robots.g1 import whole_body_g1  # noqa: E402
from mbctl.unitree.domain_lock import reserve_domain  # noqa: E402

# CI runs property tests with a fixed derivation of examples (reproducible, no flakes); local
# runs explore new examples each time.
# A suite started in the background by a shell without job control inherits SIGINT ignored, and
# so would every command the tests start: the Ctrl-C tests would then wait in vain. A handled
# signal is reset to its default on exec, an ignored one is not; so handle it here.
if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

settings.register_profile("ci", derandomize=True, deadline=None)
if os.environ.get("CI"):
    settings.load_profile("ci")


@pytest.fixture(scope="session")
def g1() -> Robot:
    """The Menagerie G1 model pair (loaded once per session; treat as read-only)."""
    try:
        return load_robot("g1")
    except ModelNotFoundError as exc:
        if os.environ.get("CI"):
            pytest.fail(f"CI must have the G1 (set MENAGERIE_ROOT): {exc}")
        pytest.skip("G1 model not on this machine (set MENAGERIE_ROOT to run the G1 tests)")


@pytest.fixture(scope="module")
def g1_torque(g1: Robot) -> Robot:
    """The G1 with torque motors, the palm sites and foot contact sensors (the whole-body jobs' robot)."""
    return whole_body_g1(g1)


@pytest.fixture(scope="session")
def two_link() -> Robot:
    """The 2-link arm with position actuators, gravity off."""
    return load_robot("two_link")


@pytest.fixture(scope="session")
def two_link_torque() -> Robot:
    """The 2-link arm with torque motors, gravity off."""
    return load_robot("two_link_torque")


@pytest.fixture(scope="session")
def two_link_torque_gravity() -> Robot:
    """The 2-link arm with torque motors and in-plane gravity (-y)."""
    return load_robot("two_link_torque", gravity=True)


@pytest.fixture(scope="session")
def dask_client():
    """A small local Dask cluster (2 processes x 1 thread) shared by the sweep tests."""
    require("dask.distributed")
    from dask.distributed import Client

    from mbctl.jobs.sweep_cluster import local_cluster

    cluster = local_cluster(2)  # as mbctl sweep starts it
    with Client(cluster) as client:
        yield client
    cluster.close()


@pytest.fixture
def dds_domain() -> Iterator[int]:
    """A DDS domain id in 1..232 for one test, reserved machine-wide while the test runs.

    The reservation (mbctl.unitree.domain_lock) holds a lock file per domain, so tests in
    other pytest processes and the benchmarks never pick the same one. Every DDS participant in
    the tests uses it on the loopback interface ``lo`` (the default of
    mbctl.unitree.Channel), so tests never share a domain and never leave the machine.
    """
    require("cyclonedds")
    with reserve_domain() as domain:
        yield domain


# ------------------------------------------------------------------------ helpers for the tests
# Test modules import these: ``from tests.conftest import first_line, require, run_mbctl``.

#: The extra that installs each optional module the tests need (all of them come with ``[test]``).
EXTRAS = {"cyclonedds": "hardware", "dask": "sweep", "playwright": "test", "sphinx": "docs", "viser": "web"}


def require(module: str) -> Any:
    """``module`` imported. Missing, it fails the test under CI (CI installs every extra), naming the
    extra that brings it, and skips it elsewhere (pytest.importorskip; also at module level)."""
    extra = EXTRAS.get(module.split(".")[0], "test")
    if not os.environ.get("CI"):
        return pytest.importorskip(module, reason=f"{module} is not installed (pip install -e '.[{extra}]')")
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        pytest.fail(f"CI must have {module} (pip install -e '.[{extra}]'): {exc}")


def mbctl_command(*args: str) -> list[str]:
    """The ``mbctl`` command line with ``args``, on this interpreter."""
    return [sys.executable, "-m", "mbctl.cli", *args]


def run_mbctl(*args: str, timeout: float = 300, env: Mapping[str, str] | None = None,
              unset: Iterable[str] = ()) -> subprocess.CompletedProcess:
    """Run ``mbctl args`` as a user would; its output as text.

    Args:
        timeout: Seconds before the command is killed (subprocess.TimeoutExpired).
        env: Variables set on top of this process's environment.
        unset: Variables removed from it.
    """
    dropped = set(unset)
    environment = {k: v for k, v in os.environ.items() if k not in dropped}
    return subprocess.run(mbctl_command(*args), capture_output=True, text=True, timeout=timeout,
                          env={**environment, **(env or {})})


def _within(call: Callable[[], str], timeout: float) -> str | None:
    """``call()`` on a thread; its result, or None if it had not returned after ``timeout`` s."""
    got: list[str] = []
    thread = threading.Thread(target=lambda: got.append(call()), daemon=True)
    thread.start()
    thread.join(timeout)
    return got[0] if got else None


def first_line(proc: subprocess.Popen, stream: str = "stderr", timeout: float = 120) -> str:
    """The first line ``proc`` writes on ``stream`` ("stdout" or "stderr", a text pipe).

    One that ends without writing a line gives what it wrote (maybe ""). One that writes no line
    within ``timeout`` s is killed and fails the test, naming the command and its stderr's tail.
    """
    pipe = getattr(proc, stream)
    got: list[str] = []
    reader = threading.Thread(target=lambda: got.append(pipe.readline()), daemon=True)
    reader.start()
    reader.join(timeout)
    if got:
        return got[0]
    proc.kill()
    proc.wait()
    reader.join(5)  # at EOF now: the reader returns what was written without a newline
    if stream == "stderr":
        err = got[0] if got else ""
    elif proc.stderr is None:
        err = "(stderr not captured)"
    else:
        err = _within(proc.stderr.read, 5) or ""
    for p in (proc.stdout, proc.stderr):
        if p is not None:
            p.close()
    pytest.fail(f"{shlex.join(map(str, proc.args))} wrote no line on {stream} within {timeout:g} s "
                f"(killed); its stderr ends with:\n{err[-2000:]}")


# ------------------------------------------------------------------------ progress per file
# `pytest -q` prints one unbroken row of dots for minutes. Show each test file on its own line
# (as pytest's default verbosity does, -q or not) and how long the previous file took, so a
# slow file reads as progress, not a hang: `tests/jobs/test_g1_jobs.py ........ (41.2 s)  [ 62%]`.
class _FileProgress:
    """Terminal lines per test file, each closed with the file's wall time."""

    def __init__(self, reporter: pytest.TerminalReporter, last_nodeid: str | None = None):
        self.reporter, self.last_nodeid = reporter, last_nodeid
        self.path: str | None = None
        self.t0 = 0.0

    def _close_line(self) -> None:
        if self.path is not None:
            self.reporter.write(f" ({time.monotonic() - self.t0:.1f} s)")
            self.path = None

    def pytest_collection_finish(self, session: pytest.Session) -> None:
        self.last_nodeid = session.items[-1].nodeid if session.items else None

    @pytest.hookimpl(tryfirst=True)  # before the reporter starts the new file's line
    def pytest_runtest_logstart(self, nodeid: str, location: tuple[str, int | None, str]) -> None:
        if location[0] != self.path:
            self._close_line()
            self.path, self.t0 = location[0], time.monotonic()

    @pytest.hookimpl(tryfirst=True)  # before the reporter writes the closing percentage
    def pytest_runtest_logfinish(self, nodeid: str) -> None:
        if nodeid == self.last_nodeid:
            self._close_line()


class _WorkersFileProgress:
    """Under pytest-xdist (``-n 2``): a line per test file once its last test reported.

    The workers' reports reach the controller interleaved, so a file's line is written when its
    count of tests is done, with the summed durations of its tests (setup, call, teardown) on
    its worker: ``tests/jobs/test_g1_jobs.py: 17 tests (34.7 s)``.
    """

    def __init__(self, reporter: pytest.TerminalReporter):
        self.reporter = reporter
        self.left: dict[str, int] | None = None
        self.total: dict[str, int] = {}
        self.seconds: dict[str, float] = {}
        self.dots = False  # the reporter wrote a test's letter since this plugin's last line

    def pytest_xdist_node_collection_finished(self, node: object, ids: list[str]) -> None:
        if self.left is None:  # every worker collects the same tests
            self.total = {}
            for nodeid in ids:
                path = nodeid.split("::", 1)[0]
                self.total[path] = self.total.get(path, 0) + 1
            self.left = dict(self.total)

    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        path = report.nodeid.split("::", 1)[0]
        self.seconds[path] = self.seconds.get(path, 0.0) + report.duration
        self.dots = self.dots or report.when == "call" or not report.passed
        if report.when != "teardown" or self.left is None or path not in self.left:
            return
        self.left[path] -= 1
        if self.left[path] == 0:
            if self.dots:
                self.reporter.write("\n")
            self.reporter.write_line(f"{path}: {self.total[path]} tests ({self.seconds[path]:.1f} s)")
            self.dots = False


@pytest.hookimpl(trylast=True)  # after the terminal reporter (and pytest-xdist's session) are registered
def pytest_configure(config: pytest.Config) -> None:
    reporter = config.pluginmanager.get_plugin("terminalreporter")
    if reporter is None or config.get_verbosity() > 0 or hasattr(config, "workerinput"):
        return  # verbose runs name every test; a worker's terminal is not shown
    if config.pluginmanager.hasplugin("dsession"):  # the controller of pytest -n N
        config.pluginmanager.register(_WorkersFileProgress(reporter), "mbctl-file-progress")
    else:
        reporter.showfspath = True
        config.pluginmanager.register(_FileProgress(reporter), "mbctl-file-progress")
