"""Unitree's low-level wire format, as both plants (the DDS robot interface, the MuJoCo bridge) use it.

``g1``: the motor table (Menagerie joint names <-> the 29 motor slots) and the IMU; ``wire``: the
``unitree_hg`` LowCmd_/LowState_ messages as numpy records and their XCDR1 bytes; ``crc``: the CRC
on the packed words; ``channel``: DDS on one domain and one network interface (``lo`` by default),
raw-bytes readers and writers. DDS needs the ``hardware`` extra; the rest needs numpy only.
"""

from mbctl.robots.unitree.channel import LOOPBACK, TOPIC_LOWCMD, TOPIC_LOWSTATE, Channel
from mbctl.robots.unitree.exceptions import ChannelError, MotorTableError, UnitreeError, WireFormatError
from mbctl.robots.unitree.g1 import G1_IMU, G1_MOTOR_JOINTS, MOTOR_SLOTS, ImuSpec, MotorMap
from mbctl.robots.unitree.wire import LOW_CMD, LOW_STATE, Codec, low_cmd_codec, low_state_codec

__all__ = [
    "G1_IMU",
    "G1_MOTOR_JOINTS",
    "LOOPBACK",
    "LOW_CMD",
    "LOW_STATE",
    "MOTOR_SLOTS",
    "TOPIC_LOWCMD",
    "TOPIC_LOWSTATE",
    "Channel",
    "ChannelError",
    "Codec",
    "ImuSpec",
    "MotorMap",
    "MotorTableError",
    "UnitreeError",
    "WireFormatError",
    "low_cmd_codec",
    "low_state_codec",
]
