"""The client's ``rt/lowcmd`` writer at connect: the robot's reader matched, no other writer beside it.

A command written before the robot's reader matched the writer is lost; a second client (or any
other program) writing ``rt/lowcmd`` on the domain would have the robot take both controllers'
commands, so the client refuses to start beside one
(:class:`~mbctl.unitree.exceptions.AnotherWriterError`, exit 2; what discovery shows within
:data:`~mbctl.unitree.channel.DISCOVERY_S` of the start). A dry run has no writer: neither applies.
"""

from __future__ import annotations

import time

from mbctl.hardware.exceptions import NoRobotError
from mbctl.unitree.channel import TOPIC_LOWCMD, TOPIC_LOWSTATE, RawWriter, WriterCount


def check_command_link(writer: RawWriter | None, others: WriterCount, domain: int, network_interface: str,
                       deadline: float, connect_timeout_s: float, discovery_until: float) -> None:
    """Wait until the robot reads ``writer``'s topic, then refuse another writer of it; stop counting.

    Args:
        writer: The client's ``rt/lowcmd`` writer (None: a dry run, nothing checked).
        others: The count of ``rt/lowcmd`` writers on the domain (closed here).
        domain: The DDS domain (in the messages).
        network_interface: The network interface (in the messages).
        deadline: When connecting gives up (``time.perf_counter``) [s].
        connect_timeout_s: The connect timeout (in the message) [s].
        discovery_until: Until when another writer is waited for (``time.perf_counter``) [s].

    Raises:
        NoRobotError: Nothing reads ``rt/lowcmd`` by ``deadline``.
        AnotherWriterError: Another ``rt/lowcmd`` writer on the domain.
    """
    try:
        if writer is None:
            return
        while not writer.matched():  # a command before that would be lost
            remaining = deadline - time.perf_counter()
            if remaining <= 0:
                raise NoRobotError(
                    f"no robot: its state arrives on {TOPIC_LOWSTATE} (DDS domain {domain}, network "
                    f"interface {network_interface!r}) but nothing reads {TOPIC_LOWCMD} within "
                    f"{connect_timeout_s:g} s: "
                    "a robot that publishes and does not listen (check its low-level mode), or a discovery "
                    "that works one way only (check the network configuration)")
            time.sleep(min(remaining, 0.005))
        others.refuse_others(1, discovery_until, "the DDS client will not command the robot: a second client "
                             "(or another program) already publishes commands there, and the robot would "
                             "take both", domain, network_interface)
    finally:
        others.close()
