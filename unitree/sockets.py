"""The UDP sockets this process holds, and pinning DDS's receive sockets to one network interface.

Cyclone DDS (cyclonedds 11.0.1, the version the ``hardware`` extra installs) binds its transmit
socket to the configured interface's address (127.0.0.1 on ``lo``) but every receive socket to
the wildcard address 0.0.0.0: the unicast discovery and data sockets (``ddsi_udp.c``,
``ddsi_udp_create_conn``: ``bind_to_any = true`` for ``DDSI_TRAN_QOS_RECV_UC``, a constant, no
configuration option changes it; its later master binds them per interface only when more than one
interface is configured) and the multicast discovery and data sockets (``DDSI_TRAN_QOS_RECV_MC``:
on Linux a socket that receives a multicast group must be bound to the wildcard or to the group's
address, never to an interface's unicast address). Bound so, a packet from another host to this
machine's address on that port would reach the participant.

Linux lets a process pin a socket to one interface after the fact (``SO_BINDTODEVICE``; without
privileges since Linux 5.7 for a socket not yet pinned): the kernel then delivers to it only packets
that arrived on that interface. :func:`pin_new_sockets` pins every wildcard UDP socket a Cyclone
domain made to the interface it was configured for; their address still reads 0.0.0.0 (``ss``
shows ``0.0.0.0%lo``), as :func:`udp_sockets` reports (address and device). On ``lo`` that is
complete: only packets from this machine reach DDS. On a real interface, packets this machine sends
to its own address on it travel through ``lo`` and are not delivered: two programs on one machine
talk over ``lo``. Not on Linux (no ``/proc/self/fd`` or no ``SO_BINDTODEVICE``) nothing is pinned
and :func:`pin_new_sockets` says so (None).
"""

from __future__ import annotations

import os
import socket
import sys
from dataclasses import dataclass

from mbctl.unitree.exceptions import ChannelError

_PROC_FILES = (("/proc/self/net/udp", socket.AF_INET), ("/proc/self/net/udp6", socket.AF_INET6))


@dataclass(frozen=True)
class UdpSocket:
    """One UDP socket of this process.

    Attributes:
        fd: Its file descriptor.
        inode: Its socket inode.
        address: The local address it is bound to ("0.0.0.0" or "::": every interface's).
        port: The local port.
        device: The interface it is pinned to (``SO_BINDTODEVICE``), or None.
    """

    fd: int
    inode: int
    address: str
    port: int
    device: str | None

    @property
    def wildcard(self) -> bool:
        """Whether it is bound to every interface's address (0.0.0.0 or ::)."""
        return self.address in ("0.0.0.0", "::")


def supported() -> bool:
    """Whether this OS lists a process's sockets (/proc) and pins them (``SO_BINDTODEVICE``)."""
    return os.path.isdir("/proc/self/fd") and hasattr(socket, "SO_BINDTODEVICE")


def _inodes() -> dict[int, int]:
    """Socket inode -> file descriptor, of this process."""
    found: dict[int, int] = {}
    for name in os.listdir("/proc/self/fd"):
        try:
            target = os.readlink(f"/proc/self/fd/{name}")
        except OSError:  # closed meanwhile
            continue
        if target.startswith("socket:["):
            found[int(target[8:-1])] = int(name)
    return found


def _address(hex_address: str, family: int) -> tuple[str, int]:
    """``0100007F:1F90`` (/proc/net/udp: the kernel's words in host order) as ("127.0.0.1", 8080)."""
    host, port = hex_address.split(":")
    raw = bytes.fromhex(host)
    if sys.byteorder == "little":
        raw = b"".join(raw[i:i + 4][::-1] for i in range(0, len(raw), 4))
    return socket.inet_ntop(family, raw), int(port, 16)


def _device(fd: int) -> str | None:
    """The interface ``fd`` is pinned to, or None."""
    dup = socket.socket(fileno=os.dup(fd))
    try:
        raw = dup.getsockopt(socket.SOL_SOCKET, socket.SO_BINDTODEVICE, 64)
    finally:
        dup.close()
    return raw.split(b"\0", 1)[0].decode() or None


def udp_sockets() -> list[UdpSocket]:
    """Every UDP socket (IPv4 and IPv6) this process holds, with its address and interface (Linux).

    Raises:
        ChannelError: Not on Linux (see :func:`supported`).
    """
    if not supported():
        raise ChannelError("listing a process's sockets needs Linux (/proc and SO_BINDTODEVICE)")
    mine = _inodes()
    found: list[UdpSocket] = []
    for path, family in _PROC_FILES:
        try:
            with open(path, encoding="ascii") as f:
                lines = f.read().splitlines()[1:]
        except FileNotFoundError:  # no IPv6 in this kernel
            continue
        for line in lines:
            fields = line.split()
            inode = int(fields[9])
            if inode in mine:
                address, port = _address(fields[1], family)
                try:
                    device = _device(mine[inode])
                except OSError:  # closed meanwhile
                    continue
                found.append(UdpSocket(mine[inode], inode, address, port, device))
    return found


def pin_new_sockets(before: set[int], interface: str) -> list[UdpSocket] | None:
    """Pin each wildcard UDP socket this process made since ``before`` (inodes) to ``interface``.

    Args:
        before: Socket inodes of :func:`udp_sockets` before the sockets were made.
        interface: The network interface (e.g. ``lo``).

    Returns:
        The sockets pinned, or None where the OS cannot (see :func:`supported`).

    Raises:
        ChannelError: The kernel refused (before Linux 5.7 pinning needs CAP_NET_RAW).
    """
    if not supported():
        return None
    pinned = []
    for s in udp_sockets():
        if s.inode in before or not s.wildcard or s.device == interface:
            continue
        dup = socket.socket(fileno=os.dup(s.fd))
        try:
            dup.setsockopt(socket.SOL_SOCKET, socket.SO_BINDTODEVICE, interface.encode())
        except OSError as exc:
            raise ChannelError(
                f"cannot pin the DDS socket on port {s.port} (bound to {s.address}) to network interface "
                f"{interface!r}: {exc} (Linux before 5.7 needs CAP_NET_RAW for SO_BINDTODEVICE); unpinned it "
                "would take packets from other hosts. Give your own Cyclone DDS configuration (--dds-config) "
                "to run as it says") from None
        finally:
            dup.close()
        pinned.append(UdpSocket(s.fd, s.inode, s.address, s.port, interface))
    return pinned


def inodes() -> set[int]:
    """The inodes of this process's UDP sockets now (empty where :func:`supported` is False)."""
    return {s.inode for s in udp_sockets()} if supported() else set()
