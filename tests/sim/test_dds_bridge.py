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


def test_a_bridge_whose_plant_diverges_says_so(g1, dds_domain, monkeypatch):
    """An acceleration beyond MAX_QACC stops the bridge naming it and the command's age (a diverged run)."""
    import numpy as np

    from mbctl.sim import dds_bridge
    from mbctl.sim.dds_bridge import BridgeDiverged, BridgeOptions, G1Bridge
    from mbctl.sim.exceptions import SimulationDiverged
    from mbctl.unitree.motors import MOTOR_ENABLED

    bridge = G1Bridge(g1, g1.keyframe_q("stand"), BridgeOptions(domain=dds_domain, lockstep=True))
    try:
        command = np.zeros(bridge.motors.n, dtype=dds_bridge.low_cmd_codec().message["motor_cmd"].dtype)
        command["mode"] = MOTOR_ENABLED
        bridge.step(0.1, command.copy())  # a sane step: no torque, the robot starts to sag
        assert 0 < bridge.peak_qacc < dds_bridge.MAX_QACC
        monkeypatch.setattr(dds_bridge, "MAX_QACC", bridge.peak_qacc / 10)  # the bound moved, not the physics
        expected = (r"diverged near t=0\.0020 s: an acceleration of .* after its last command had been "
                    r"applied for 0\.150 s \(stale torques")
        with pytest.raises(BridgeDiverged, match=expected) as err:
            bridge.step(0.25)
        assert isinstance(err.value, SimulationDiverged)  # the runner's "diverged": exit 1
    finally:
        bridge.close()


def test_lockstep_refuses_a_link_model():
    from mbctl.sim.dds_bridge import BridgeOptions
    from mbctl.sim.exceptions import SimError
    from mbctl.sim.link import LinkSpec

    with pytest.raises(SimError, match="latency, jitter and drops need a wall clock"):
        BridgeOptions(link=LinkSpec(latency_ms=2.0), lockstep=True)
