"""Waiting for a bridge process to serve: its line, its failure, its silence (fake processes, no DDS)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
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


def _lowcmd(bridge, q_all, **fields):
    """A valid LowCmd_ (wire bytes) for ``bridge``: every motor enabled at ``q_all`` (n,), then
    ``fields`` {name: {motor: value}}."""
    from mbctl.unitree.motors import MODE_PR, MOTOR_ENABLED
    from mbctl.unitree.wire import low_cmd_codec

    codec = low_cmd_codec()
    msg = codec.message
    msg["mode_pr"], msg["mode_machine"] = MODE_PR, bridge.options.mode_machine
    motors = msg["motor_cmd"]
    motors["mode"][: bridge.motors.n] = MOTOR_ENABLED
    motors["q"][: bridge.motors.n] = q_all
    for name, values in fields.items():
        for i, value in values.items():
            motors[name][i] = value
    return codec.encode()


def test_every_field_is_clamped_to_its_range_and_counted_per_motor(g1, dds_domain):
    """Gains and velocity targets to the table's bounds, q to the joint range, tau to the torque limit."""
    from mbctl.sim.dds_bridge import BridgeOptions, G1Bridge
    from mbctl.unitree.tables import G1_29DOF

    bridge = G1Bridge(g1, g1.keyframe_q("stand"), BridgeOptions(domain=dds_domain, lockstep=True))
    try:
        m = bridge.motors
        q = np.clip(g1.keyframe_q("stand")[7:], m.q_low, m.q_high)
        # motor 6 disabled: its junk is clamped too but not counted (it exerts nothing)
        wire = _lowcmd(bridge, q, kp={0: 1e30, 1: -5.0, 6: 1e30}, kd={2: 1e6}, dq={3: -1e4}, q={4: 100.0},
                       tau={5: -1e9}, mode={6: 0})
        motors = bridge._valid_command(wire)
        assert motors["kp"][0] == np.float32(G1_29DOF.kp_max) == np.float32(1000.0) and motors["kp"][1] == 0
        assert motors["kd"][2] == np.float32(100.0) and motors["dq"][3] == np.float32(-30.0)
        assert motors["q"][4] == np.float32(m.q_high[4]) and motors["tau"][5] == np.float32(-m.tau_max[5])
        assert bridge.counts["commands_clamped"] == 1
        assert bridge.stats()["clamped_per_motor"] == {j: 1 for j in m.joints[:6]}
        assert bridge._valid_command(_lowcmd(bridge, q)) is not None  # in range: nothing clamped
        assert bridge.counts["commands_clamped"] == 1
    finally:
        bridge.close()


def test_a_kp_of_1e30_over_dds_is_clamped_and_the_lockstep_plant_stays_finite(g1, dds_domain):
    """One valid LowCmd with kp = 1e30 (the left knee's, target 0.3 rad) made MuJoCo's ctrl overflow
    (BADCTRL: the bridge stopped as diverged)."""
    import threading

    from mbctl.sim.dds_bridge import MAX_QACC, BridgeOptions, G1Bridge
    from mbctl.unitree import TOPIC_LOWCMD, Channel
    from mbctl.unitree.channel import message_types

    bridge = G1Bridge(g1, g1.keyframe_q("stand"), BridgeOptions(domain=dds_domain, lockstep=True))
    client = Channel(dds_domain)
    try:
        writer = client.writer(TOPIC_LOWCMD, message_types()[0])
        q = g1.keyframe_q("stand")[7:]
        knee = bridge.motors.joints.index("left_knee_joint")
        outcome: dict[str, object] = {}

        def serve():
            try:
                outcome["stopped"] = bridge.serve(idle_timeout_s=2.0)
            except Exception as exc:  # noqa: BLE001 - the test reports it
                outcome["error"] = exc

        thread = threading.Thread(target=serve)
        thread.start()
        while not writer.matched() and thread.is_alive():
            thread.join(0.005)
        for _ in range(10):
            writer.write(_lowcmd(bridge, q, kp={knee: 1e30}, q={knee: 0.3}))
            thread.join(0.01)
        thread.join()
        assert outcome == {"stopped": "idle"}  # not diverged
        stats = bridge.stats()
        assert stats["commands_applied"] >= 1 and stats["commands_clamped"] == stats["commands_applied"]
        assert stats["clamped_per_motor"] == {"left_knee_joint": stats["commands_applied"]}
        assert np.isfinite(bridge.sim.data.qpos).all() and bridge.peak_qacc < MAX_QACC
    finally:
        client.close()
        bridge.close()


def test_a_second_bridge_on_the_domain_refuses_to_start(g1, dds_domain):
    """Two participants on the test's domain: the first bridge, then another writer of rt/lowstate."""
    from mbctl.sim.dds_bridge import BridgeOptions, G1Bridge
    from mbctl.unitree.exceptions import AnotherWriterError, ChannelError

    first = G1Bridge(g1, g1.keyframe_q("stand"), BridgeOptions(domain=dds_domain, lockstep=True))
    try:
        expected = (r"^the G1 bridge \(mbctl serve g1\) will not start: a second bridge or a robot already "
                    rf"publishes its state there, .*: 1 other writer of rt/lowstate already on DDS domain "
                    rf"{dds_domain} \(network interface 'lo'\); refusing to start beside it")
        with pytest.raises(AnotherWriterError, match=expected) as err:
            G1Bridge(g1, g1.keyframe_q("stand"), BridgeOptions(domain=dds_domain, lockstep=True))
        assert isinstance(err.value, ChannelError)  # a ToolkitError at prepare: exit 2
    finally:
        first.close()
    again = G1Bridge(g1, g1.keyframe_q("stand"), BridgeOptions(domain=dds_domain, lockstep=True))
    again.close()  # alone on the domain it starts


def test_mbctl_serve_beside_another_state_writer_exits_2_naming_it(dds_domain, tmp_path):
    from mbctl.unitree import TOPIC_LOWSTATE, Channel
    from mbctl.unitree.channel import message_types
    from tests.conftest import run_mbctl

    with Channel(dds_domain) as other:
        other.writer(TOPIC_LOWSTATE, message_types()[1])
        out = run_mbctl("serve", "g1", "--domain", str(dds_domain), "--duration", "1", "--lockstep",
                        "--output", str(tmp_path / "serve"))
    assert out.returncode == 2, out.stderr
    assert f"1 other writer of rt/lowstate already on DDS domain {dds_domain}" in out.stderr


def test_a_bridge_on_lo_holds_no_socket_another_host_can_reach(g1, dds_domain):
    """Its receive sockets are on 0.0.0.0 (Cyclone's constant) pinned to lo; its transmit one on 127.0.0.1."""
    from mbctl.sim.dds_bridge import BridgeOptions, G1Bridge
    from mbctl.unitree.sockets import supported, udp_sockets

    if not supported():
        pytest.skip("needs Linux (/proc and SO_BINDTODEVICE)")
    before = {s.inode for s in udp_sockets()}  # the test process's own (other tests')
    bridge = G1Bridge(g1, g1.keyframe_q("stand"), BridgeOptions(domain=dds_domain, lockstep=True))
    try:
        held = [s for s in udp_sockets() if s.inode not in before]
    finally:
        bridge.close()
    assert len(held) == 5 and sorted(s.device or s.address for s in held) == ["127.0.0.1"] + ["lo"] * 4
