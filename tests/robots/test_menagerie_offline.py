"""An offline G1 fails fast: one bounded connection attempt, no retries of the download."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import threading

import pytest

from mbctl.robots import ModelNotFoundError, menagerie


@pytest.fixture
def closed_port() -> int:
    """A loopback port nothing listens on."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def offline(monkeypatch, tmp_path, closed_port):
    """No MENAGERIE_ROOT, an empty cache, and the download host a closed 127.0.0.1 port."""
    monkeypatch.delenv("MENAGERIE_ROOT", raising=False)
    monkeypatch.setenv("MENAGERIE_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setenv("MENAGERIE_BASE_URL", f"http://127.0.0.1:{closed_port}")
    return closed_port


def test_an_unreachable_download_host_fails_without_downloading(offline, monkeypatch):
    import mujoco_menagerie._cache as cache

    attempts = []
    monkeypatch.setattr(cache.urllib.request, "urlopen", lambda *a, **k: attempts.append(a) or
                        (_ for _ in ()).throw(OSError("refused")))
    monkeypatch.setattr(cache.time, "sleep", lambda s: attempts.append(s))
    message = f"cannot be downloaded: cannot connect to 127.0.0.1:{offline} \\(ConnectionRefusedError"
    with pytest.raises(ModelNotFoundError, match=message + ".*Set MENAGERIE_ROOT"):
        menagerie.resolve_menagerie_dir("unitree_g1")
    assert attempts == []  # no download tried, so none of its three tries and back-off sleeps


def test_a_host_that_never_answers_is_given_up_after_the_timeout(monkeypatch):
    release = threading.Event()

    def hang(*args, **kwargs):
        release.wait(5)
        return socket.socket()  # closed by the probe

    monkeypatch.setattr(socket, "create_connection", hang)
    try:
        assert menagerie._unreachable("https://example.invalid/x", timeout_s=0.2) == \
            "no connection to example.invalid:443 within 0.2 s"
    finally:
        release.set()
    assert menagerie._unreachable("file:///tmp/archive") is None
    assert menagerie.CONNECT_TIMEOUT_S <= 2.0  # the bound is 3 s in all


def test_cli_offline_g1_exits_2_naming_the_host(offline):
    env = {k: v for k, v in os.environ.items() if k != "MENAGERIE_ROOT"}
    out = subprocess.run([sys.executable, "-m", "mbctl.cli", "inspect", "g1"], capture_output=True, text=True,
                         timeout=60, env=env)
    assert out.returncode == 2, out.stderr
    assert f"cannot connect to 127.0.0.1:{offline}" in out.stderr and "--model-dir" in out.stderr
