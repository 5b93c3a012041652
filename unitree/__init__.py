"""Unitree's low-level floor: the ``unitree_hg`` protocol both plants (the DDS interface, the bridge) speak.

It sits beside robots/ and below the two plants (``mbctl.hardware`` and ``mbctl.sim.dds_bridge``),
generic over the robots that speak ``unitree_hg``; a robot is a :class:`MotorTable` (data):

- ``tables``: the motor tables (the G1's 29- and 23-dof ones) and their IMU;
- ``motors``: a table resolved once in a model (:class:`MotorMap`: q/v indices, actuators, limits);
- ``wire``: ``LowCmd_``/``LowState_`` as numpy records and their XCDR1 bytes; ``crc``: the CRC on
  the packed words;
- ``channel``: DDS on one domain and one network interface (``lo`` by default), raw-bytes readers
  and writers, the writers of a topic counted; ``sockets``: its receive sockets listed and pinned to
  that interface; ``domain_lock``: one test or bench per domain on this machine;
- ``clock``: the wall-clock cycle pacing and its statistics, and real-time priority for a loop.

DDS needs the ``hardware`` extra; the rest needs numpy only.
"""

from mbctl.unitree.channel import LOOPBACK, TOPIC_LOWCMD, TOPIC_LOWSTATE, Channel
from mbctl.unitree.clock import CycleClock, PeriodStats, RealtimePriority
from mbctl.unitree.exceptions import (
    AnotherWriterError,
    ChannelError,
    MotorTableError,
    UnitreeError,
    WireFormatError,
)
from mbctl.unitree.motors import MOTOR_SLOTS, MotorMap
from mbctl.unitree.tables import G1_23DOF, G1_29DOF, G1_MOTOR_JOINTS, TABLES, MotorTable
from mbctl.unitree.wire import LOW_CMD, LOW_STATE, Codec, low_cmd_codec, low_state_codec

__all__ = [
    "AnotherWriterError",
    "G1_23DOF",
    "G1_29DOF",
    "G1_MOTOR_JOINTS",
    "LOOPBACK",
    "LOW_CMD",
    "LOW_STATE",
    "MOTOR_SLOTS",
    "TABLES",
    "TOPIC_LOWCMD",
    "TOPIC_LOWSTATE",
    "Channel",
    "ChannelError",
    "Codec",
    "CycleClock",
    "MotorMap",
    "MotorTable",
    "MotorTableError",
    "PeriodStats",
    "RealtimePriority",
    "UnitreeError",
    "WireFormatError",
    "low_cmd_codec",
    "low_state_codec",
]
