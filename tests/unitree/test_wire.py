"""The Unitree wire layer against Unitree's own types and CRC: motor table, XCDR1 bytes, CRC, raw DDS."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

# Unitree's own IDL types and CRC helper (the hardware extra, which the test extra installs)
from unitree_sdk2py.idl.unitree_hg.msg.dds_ import IMUState_, LowCmd_, LowState_, MotorCmd_, MotorState_
from unitree_sdk2py.utils.crc import CRC

from mbctl.robots.exceptions import UnknownNameError
from mbctl.unitree import (
    G1_MOTOR_JOINTS,
    LOW_CMD,
    LOW_STATE,
    MotorMap,
    MotorTableError,
    WireFormatError,
    low_cmd_codec,
    low_state_codec,
)
from mbctl.unitree.channel import (
    TOPIC_LOWCMD,
    TOPIC_LOWSTATE,
    Channel,
    ChannelError,
    check_network_interface,
    domain_config,
    message_types,
)
from mbctl.unitree.crc import crc32_reference, crc32_words
from mbctl.unitree.motors import motor_index, motor_joint
from mbctl.unitree.wire import cdr_index


# ---------------------------------------------------------------- the motor table
def test_motor_table_round_trip_both_ways(g1):
    assert len(G1_MOTOR_JOINTS) == 29 == len(set(G1_MOTOR_JOINTS))
    for i, joint in enumerate(G1_MOTOR_JOINTS):
        assert motor_index(joint) == i
        assert motor_joint(i) == joint
    motors = MotorMap.for_robot(g1)
    for i, joint in enumerate(motors.joints):
        assert g1.joint(joint).idx_q == motors.idx_q[i]
        assert g1.joint(joint).idx_v == motors.idx_v[i]
        assert g1.actuator_for_joint(joint).index == motors.actuator[i]
    # Unitree's G1JointIndex: left knee 3, right hip pitch 6, waist yaw 12, right wrist yaw 28
    unitree = {"left_knee_joint": 3, "right_hip_pitch_joint": 6, "waist_yaw_joint": 12,
               "left_shoulder_pitch_joint": 15, "right_wrist_yaw_joint": 28}
    assert {j: motor_index(j) for j in unitree} == unitree
    assert motors.tau_max[motor_index("left_knee_joint")] == 139.0
    assert motors.tau_max[motor_index("left_wrist_yaw_joint")] == 5.0


def test_motor_table_names_bad_lookups(two_link):
    with pytest.raises(UnknownNameError, match="left_knee_joint"):
        motor_index("left_kne_joint")
    with pytest.raises(UnknownNameError, match="motor index"):
        motor_joint(29)
    with pytest.raises(MotorTableError, match="joints missing from the robot"):
        MotorMap.for_robot(two_link)


# ---------------------------------------------------------------- messages and CRC
def _random_cmd(rng):
    codec = low_cmd_codec()
    m = codec.message
    m["mode_pr"], m["mode_machine"] = rng.integers(0, 2), rng.integers(0, 256)
    mc = m["motor_cmd"]
    mc["mode"] = rng.integers(0, 2, 35)
    for f in ("q", "dq", "tau", "kp", "kd"):
        mc[f] = rng.normal(size=35) * 10
    mc["reserve"] = rng.integers(0, 2**32, 35, dtype=np.uint64)
    m["reserve"] = rng.integers(0, 2**32, 4, dtype=np.uint64)
    idl = LowCmd_(int(m["mode_pr"]), int(m["mode_machine"]),
                  [MotorCmd_(int(x["mode"]), *(float(x[f]) for f in ("q", "dq", "tau", "kp", "kd")),
                             int(x["reserve"])) for x in mc], [int(r) for r in m["reserve"]], 0)
    return codec, idl


def _random_state(rng):
    codec = low_state_codec()
    m = codec.message
    m["version"] = rng.integers(0, 2**32, 2, dtype=np.uint64)
    m["mode_pr"], m["mode_machine"] = rng.integers(0, 2), rng.integers(0, 256)
    m["tick"] = rng.integers(0, 2**32)
    imu = m["imu_state"]
    for f in ("quaternion", "gyroscope", "accelerometer", "rpy"):
        imu[f] = rng.normal(size=imu[f].shape)
    imu["temperature"] = rng.integers(-100, 100)
    ms = m["motor_state"]
    ms["mode"] = rng.integers(0, 2, 35)
    for f in ("q", "dq", "ddq", "tau_est", "vol"):
        ms[f] = rng.normal(size=35)
    ms["temperature"] = rng.integers(-100, 100, (35, 2))
    for f in ("sensor", "reserve"):
        ms[f] = rng.integers(0, 2**32, ms[f].shape, dtype=np.uint64)
    ms["motorstate"] = rng.integers(0, 2**32, 35, dtype=np.uint64)
    m["wireless_remote"] = rng.integers(0, 256, 40)
    m["reserve"] = rng.integers(0, 2**32, 4, dtype=np.uint64)
    idl = LowState_(
        [int(v) for v in m["version"]], int(m["mode_pr"]), int(m["mode_machine"]), int(m["tick"]),
        IMUState_(*(imu[f].tolist() for f in ("quaternion", "gyroscope", "accelerometer", "rpy")),
                  int(imu["temperature"])),
        [MotorState_(int(x["mode"]), *(float(x[f]) for f in ("q", "dq", "ddq", "tau_est")),
                     x["temperature"].tolist(), float(x["vol"]), x["sensor"].tolist(), int(x["motorstate"]),
                     x["reserve"].tolist()) for x in ms],
        m["wireless_remote"].tolist(), m["reserve"].tolist(), 0)
    return codec, idl


def test_c_layout_sizes_are_unitree_structs():
    # the sizes of Unitree's C++ structs (and of their Python CRC helper's pack formats)
    assert (LOW_CMD.itemsize, LOW_STATE.itemsize) == (1004, 2092)
    assert cdr_index(LOW_CMD).size == len(LowCmd_(0, 0, [MotorCmd_(0, 0, 0, 0, 0, 0, 0)] * 35, [0] * 4, 0)
                                          .serialize()) - 4


@pytest.mark.parametrize("make", [_random_cmd, _random_state], ids=["LowCmd_", "LowState_"])
@pytest.mark.parametrize("seed", range(5))
def test_wire_bytes_and_crc_match_unitree(make, seed):
    codec, idl = make(np.random.default_rng(seed))
    wire = codec.encode()
    idl.crc = CRC().Crc(idl)  # Unitree's helper: repacks field by field, its own C CRC
    assert int(codec.message["crc"]) == idl.crc
    assert wire == idl.serialize()  # cyclonedds' serializer of Unitree's IDL type
    other = type(codec)(codec.dtype)
    assert other.decode(idl.serialize())
    assert other.packed.tobytes() == codec.packed.tobytes()


@given(st.lists(st.integers(0, 2**32 - 1), min_size=1, max_size=64))
def test_crc_on_packed_words_equals_the_bitwise_definition(words):
    arr = np.array(words, dtype=np.uint32)
    assert crc32_words(arr.view(np.uint8)) == crc32_reference(arr)


def test_bad_crc_and_other_encodings_are_detected():
    codec, idl = _random_cmd(np.random.default_rng(7))
    wire = bytearray(codec.encode())
    wire[40] ^= 0x01  # one bit of motor 1's q
    assert not low_cmd_codec().decode(bytes(wire))
    with pytest.raises(WireFormatError, match="little-endian XCDR1"):
        low_cmd_codec().decode(idl.serialize(use_version_2=True))
    with pytest.raises(WireFormatError, match="got 10 bytes"):
        low_cmd_codec().decode(b"\x00\x01\x00\x00" + bytes(6))


# ---------------------------------------------------------------- DDS on loopback
def test_raw_bytes_round_trip_with_the_public_api(dds_domain):
    from cyclonedds.pub import DataWriter
    from cyclonedds.sub import DataReader

    cmd_type, _ = message_types()
    codec, idl = _random_cmd(np.random.default_rng(3))
    with Channel(dds_domain) as a, Channel(dds_domain) as b:
        raw_writer, raw_reader = a.writer(TOPIC_LOWCMD, cmd_type), b.reader(TOPIC_LOWCMD, cmd_type)
        public_reader = DataReader(b._participant, b._topic(TOPIC_LOWCMD, cmd_type))
        public_writer = DataWriter(a._participant, a._topic(TOPIC_LOWCMD, cmd_type))
        deadline = time.monotonic() + 5
        got: list[bytes] = []
        while not got and time.monotonic() < deadline:  # until discovery matched them
            raw_writer.write(codec.encode())
            raw_reader.wait(0.05)
            got = raw_reader.take()
        assert got and got[-1] == codec.encode()
        assert public_reader.take(8)[-1] == idl.__class__.deserialize(codec.encode())
        idl.crc = 5
        public_writer.write(idl)
        assert raw_reader.wait(1.0)
        assert raw_reader.take()[-1] == idl.serialize()


def test_channel_checks_its_inputs_and_stays_on_loopback(dds_domain):
    with pytest.raises(ChannelError, match="domain must be an integer in 0..232"):
        Channel(233)
    with pytest.raises(ChannelError, match="no network interface 'eth-nope'.*lo"):
        check_network_interface("eth-nope")
    config = domain_config("lo")
    # one interface, lo: multicast there stays on the machine (and is what Unitree's SDK uses on lo)
    assert config.count("<NetworkInterface ") == 1
    assert '<NetworkInterface name="lo" multicast="true"/>' in config
    assert '<Peer address="127.0.0.1"/>' in config


def test_a_user_cyclone_config_is_used_as_written(tmp_path):
    mine = tmp_path / "cyclone.xml"
    mine.write_text("<CycloneDDS><Domain Id='any'/></CycloneDDS>")
    assert domain_config("lo", str(mine)) == mine.read_text()
    with pytest.raises(ChannelError, match=r"cannot read the Cyclone DDS configuration '.*nope.xml'"):
        domain_config("lo", str(tmp_path / "nope.xml"))


#: A process on Unitree's SDK configuration of ``lo`` (ChannelFactoryInitialize), publishing LowState_
#: and counting the LowCmd_ it gets, as Unitree's simulator does.
_SDK_PEER = """
import sys, time
from unitree_sdk2py.core.channel import ChannelFactoryInitialize, ChannelPublisher, ChannelSubscriber
from unitree_sdk2py.idl.default import unitree_hg_msg_dds__LowState_
from unitree_sdk2py.idl.unitree_hg.msg.dds_ import LowCmd_, LowState_
ChannelFactoryInitialize(int(sys.argv[1]), "lo")
got = []
ChannelSubscriber("rt/lowcmd", LowCmd_).Init(lambda msg: got.append(msg.motor_cmd[0].tau), 10)
publisher = ChannelPublisher("rt/lowstate", LowState_)
publisher.Init()
state = unitree_hg_msg_dds__LowState_()
state.tick = 7
deadline = time.monotonic() + 30
while time.monotonic() < deadline and not got:
    publisher.Write(state)
    time.sleep(0.005)
print(got[0] if got else "none", flush=True)
"""


def test_unitree_s_sdk_on_lo_and_mbctl_see_each_other(dds_domain):
    """Discovery on lo as Unitree's SDK configures it (multicast): its LowState reaches us, our LowCmd it."""
    peer = subprocess.Popen([sys.executable, "-c", _SDK_PEER, str(dds_domain)], stdout=subprocess.PIPE,
                            text=True)
    try:
        cmd_type, state_type = message_types()
        with Channel(dds_domain) as channel:
            reader = channel.reader(TOPIC_LOWSTATE, state_type)
            writer = channel.writer(TOPIC_LOWCMD, cmd_type)
            state = low_state_codec()
            assert reader.wait(30.0), "no LowState from the SDK's process on lo"
            assert state.decode(reader.take()[-1]) is False  # it sends CRC 0
            assert int(state.message["tick"]) == 7
            cmd = low_cmd_codec()
            cmd.message["motor_cmd"]["tau"][0] = 1.5
            deadline = time.monotonic() + 30
            while peer.poll() is None and time.monotonic() < deadline:
                writer.write(cmd.encode())
                time.sleep(0.01)
        out = peer.communicate(timeout=30)[0]
    finally:
        if peer.poll() is None:
            peer.kill()
            peer.wait()
    assert out.strip() == "1.5"


def _round_trip(channel: Channel) -> bytes | None:
    """Publish a LowCmd on ``channel`` and take it back there: the bytes received, or None in 5 s."""
    cmd_type, _ = message_types()
    writer, reader = channel.writer(TOPIC_LOWCMD, cmd_type), channel.reader(TOPIC_LOWCMD, cmd_type)
    wire = _random_cmd(np.random.default_rng(11))[0].encode()
    deadline = time.monotonic() + 5
    while time.monotonic() < deadline:  # until discovery matched them
        writer.write(wire)
        reader.wait(0.05)
        got = reader.take()
        if got:
            assert got[-1] == wire
            return got[-1]
    return None


def test_closing_one_channel_leaves_the_shared_domain_to_the_other(dds_domain):
    """Two participants of one process share the domain's configuration (counted, released last)."""
    a, b = Channel(dds_domain), Channel(dds_domain)
    try:
        a.close()
        assert _round_trip(b) is not None
    finally:
        b.close()


def test_a_domain_cyclone_cannot_create_is_a_channel_error(dds_domain, monkeypatch):
    """An interface that passes the name check but that Cyclone cannot use: ChannelError, not DDS's."""
    import mbctl.unitree.channel as channel_module

    # no interface of that name exists: Cyclone fails while configuring, before any traffic
    monkeypatch.setattr(channel_module, "check_network_interface", lambda name: name)
    with pytest.raises(ChannelError, match=rf"cannot create DDS domain {dds_domain} on network "
                                           r"interface 'mbctl-none0': "):
        Channel(dds_domain, "mbctl-none0")
    with Channel(dds_domain) as channel:  # the failed attempt left the domain free
        assert channel.network_interface == "lo"


def test_a_domain_open_on_one_interface_is_refused_on_another(dds_domain, monkeypatch):
    import mbctl.unitree.channel as channel_module

    # the refusal comes before any DDS entity is made, so the other interface need not exist here
    monkeypatch.setattr(channel_module, "check_network_interface", lambda name: name)
    with Channel(dds_domain) as a:
        expected = (f"DDS domain {dds_domain} is already open on 'lo' in this process; "
                    "cannot also open it on 'eth-test'")
        with pytest.raises(ChannelError, match=f"^{re.escape(expected)}$"):
            Channel(dds_domain, "eth-test")
        assert _round_trip(a) is not None  # the refused open left the open one working


def test_closing_a_channel_stops_its_threads(dds_domain):
    """Cyclone's threads (receive, timed events, delivery queues, gc) end with the last channel of
    the domain. They are C threads, unknown to ``threading``: compare the OS thread ids started by
    this channel, not counts (other threads of the process may come and go meanwhile)."""

    def task_ids() -> set[int]:
        return {int(t) for t in os.listdir("/proc/self/task")}

    def python_threads() -> set[int]:
        return {t.native_id for t in threading.enumerate()}

    before = task_ids()
    channel = Channel(dds_domain)
    channel.reader(TOPIC_LOWCMD, message_types()[0])
    started = task_ids() - before - python_threads()
    assert started  # the channel's own threads
    channel.close()
    channel.close()  # idempotent
    deadline = time.monotonic() + 2
    while started & task_ids() and time.monotonic() < deadline:
        time.sleep(0.01)
    assert not started & task_ids()
