"""Waiting for a bridge process to serve: its line, its failure, its silence (fake processes, no DDS)."""

from __future__ import annotations

import subprocess
import sys

import pytest

from mbctl.sim.dds_bridge import SERVING, BridgeStartError, wait_until_serving


def _process(code: str) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            text=True)


def test_the_serving_line_is_returned_and_the_process_keeps_running():
    proc = _process(f"import sys, time; print('mbctl serve g1: {SERVING} 7', file=sys.stderr, flush=True); "
                    "time.sleep(30)")
    try:
        assert wait_until_serving(proc, timeout_s=60) == f"mbctl serve g1: {SERVING} 7\n"
        assert proc.poll() is None
    finally:
        proc.kill()
        proc.wait()
        proc.stderr.close()


def test_a_bridge_that_fails_is_reported_with_its_stderr():
    proc = _process("import sys; print('error: no G1 here', file=sys.stderr); "
                    "print('exit 2', file=sys.stderr)")
    with pytest.raises(BridgeStartError, match=r"^the DDS bridge did not start: error: no G1 here\nexit 2$"):
        wait_until_serving(proc, timeout_s=60)
    proc.wait()
    proc.stderr.close()


def test_a_silent_bridge_is_killed_after_the_timeout():
    proc = _process("import time; time.sleep(60)")
    with pytest.raises(BridgeStartError, match=rf"wrote no '{SERVING}' line within 0.5 s \(killed\)"):
        wait_until_serving(proc, timeout_s=0.5)  # the configured timeout, named: no wall-clock bound
    assert proc.wait(timeout=5) != 0  # killed
    proc.stderr.close()
