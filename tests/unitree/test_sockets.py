"""DDS's sockets on ``lo``: none takes packets from another host (bound to 127.0.0.1 or pinned to lo)."""

from __future__ import annotations

import socket

import pytest

from mbctl.unitree import TOPIC_LOWCMD, TOPIC_LOWSTATE, Channel
from mbctl.unitree.channel import message_types
from mbctl.unitree.sockets import supported, udp_sockets

pytestmark = pytest.mark.skipif(not supported(), reason="needs Linux (/proc and SO_BINDTODEVICE)")


def open_to_other_hosts():
    """This process's UDP sockets another host could reach: on the wildcard address, pinned to no
    interface but ``lo`` (or bound to an address not on ``lo``)."""
    return [s for s in udp_sockets()
            if (s.wildcard and s.device != "lo") or not (s.wildcard or s.address.startswith("127."))]


def domain_ports(domain):
    """The ports of ``domain`` in the DDSI port mapping: 7400 + 250 d + 0..249."""
    base = 7400 + 250 * domain
    return range(base, base + 250)


def test_a_channel_on_lo_holds_no_socket_another_host_can_reach(dds_domain):
    before = {s.inode for s in udp_sockets()}  # the test process's own (other tests') before DDS
    lowcmd, lowstate = message_types()
    with Channel(dds_domain) as channel:
        channel.writer(TOPIC_LOWCMD, lowcmd)
        channel.reader(TOPIC_LOWSTATE, lowstate)
        held = [s for s in udp_sockets() if s.inode not in before]
        assert [s for s in open_to_other_hosts() if s.inode not in before] == []
    # Cyclone's receive sockets (multicast discovery and data: ports d0, d2 = +0, +1; unicast: d1 +
    # 2 i, d3 + 2 i = +10 + 2 i, +11 + 2 i) are on 0.0.0.0, pinned to lo; its transmit socket on 127.0.0.1
    pinned = sorted(s.port - domain_ports(dds_domain).start for s in held if s.wildcard)
    assert len(pinned) == 4 and pinned[:2] == [0, 1] and pinned[3] == pinned[2] + 1 and pinned[2] % 2 == 0
    assert all(s.device == "lo" for s in held if s.wildcard)
    assert [s.address for s in held if not s.wildcard] == ["127.0.0.1"]
    assert [s for s in udp_sockets() if s.inode not in before] == []  # closing the channel closed them


def test_the_listing_reads_addresses_and_devices_as_the_kernel_has_them():
    plain = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    pinned = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    local = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        plain.bind(("0.0.0.0", 0))
        pinned.bind(("0.0.0.0", 0))
        pinned.setsockopt(socket.SOL_SOCKET, socket.SO_BINDTODEVICE, b"lo")
        local.bind(("127.0.0.1", 0))
        listed = {s.fd: (s.address, s.port, s.device) for s in udp_sockets()}
        assert listed[plain.fileno()] == ("0.0.0.0", plain.getsockname()[1], None)
        assert listed[pinned.fileno()] == ("0.0.0.0", pinned.getsockname()[1], "lo")
        assert listed[local.fileno()] == ("127.0.0.1", local.getsockname()[1], None)
        assert [s.fd for s in open_to_other_hosts()] == [plain.fileno()]
    finally:
        for s in (plain, pinned, local):
            s.close()
