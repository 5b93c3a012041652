"""The ``unitree_hg`` LowCmd_ and LowState_ messages as numpy records, and their wire bytes.

A message lives in a numpy structured array with the C struct's layout (``align=True`` gives the
same offsets as Unitree's C++ structs and their Python CRC helper's pack formats: 1004 bytes for
LowCmd_, 2092 for LowState_). Fields are filled with whole-array assignments
(``motor_cmd["q"][:29] = q``), the CRC is computed on those bytes (:mod:`mbctl.unitree.crc`),
and the bytes on the wire are the XCDR1 little-endian serialization DDS sends: the same fields in
the same order, but each aligned to its own size from the start of the payload, so the
serialization differs from the C layout around the first motor (CDR puts ``motor_cmd[0].mode``
right after ``mode_machine``). The two layouts are related by a byte permutation computed once
from the dtype (:func:`cdr_index`); converting a message is one numpy gather.

Tests check the wire bytes against the IDL types' own serializer (unitree_sdk2py, cyclonedds) and
the CRC against Unitree's helper, on random messages.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from mbctl.unitree.crc import crc32_words
from mbctl.unitree.exceptions import WireFormatError
from mbctl.unitree.motors import MOTOR_SLOTS

MOTOR_CMD = np.dtype([("mode", "u1"), ("q", "<f4"), ("dq", "<f4"), ("tau", "<f4"), ("kp", "<f4"),
                      ("kd", "<f4"), ("reserve", "<u4")], align=True)
#: The ``unitree_hg`` ``LowCmd_`` message as a numpy record (aligned as its XCDR1 bytes).
LOW_CMD = np.dtype([("mode_pr", "u1"), ("mode_machine", "u1"), ("motor_cmd", MOTOR_CMD, (MOTOR_SLOTS,)),
                    ("reserve", "<u4", (4,)), ("crc", "<u4")], align=True)
IMU_STATE = np.dtype([("quaternion", "<f4", (4,)), ("gyroscope", "<f4", (3,)), ("accelerometer", "<f4", (3,)),
                      ("rpy", "<f4", (3,)), ("temperature", "<i2")], align=True)
MOTOR_STATE = np.dtype([("mode", "u1"), ("q", "<f4"), ("dq", "<f4"), ("ddq", "<f4"), ("tau_est", "<f4"),
                        ("temperature", "<i2", (2,)), ("vol", "<f4"), ("sensor", "<u4", (2,)),
                        ("motorstate", "<u4"), ("reserve", "<u4", (4,))], align=True)
#: The ``unitree_hg`` ``LowState_`` message as a numpy record (aligned as its XCDR1 bytes).
LOW_STATE = np.dtype([("version", "<u4", (2,)), ("mode_pr", "u1"), ("mode_machine", "u1"), ("tick", "<u4"),
                      ("imu_state", IMU_STATE), ("motor_state", MOTOR_STATE, (MOTOR_SLOTS,)),
                      ("wireless_remote", "u1", (40,)), ("reserve", "<u4", (4,)), ("crc", "<u4")],
                     align=True)

#: RTPS encapsulation header of little-endian XCDR1 (what the robot and cyclonedds' writers send).
XCDR1_LE = b"\x00\x01\x00\x00"


def _leaves(dt: np.dtype, base: int = 0) -> Iterator[tuple[int, int]]:
    """(offset in the C layout, size) of every primitive of ``dt``, in declaration order."""
    if dt.subdtype is not None:
        sub, shape = dt.subdtype
        for k in range(int(np.prod(shape))):
            yield from _leaves(sub, base + k * sub.itemsize)
    elif dt.names:
        for name in dt.names:
            field, offset = dt.fields[name][:2]  # type: ignore[index]
            yield from _leaves(field, base + offset)
    else:
        yield base, dt.itemsize


def cdr_index(dt: np.dtype) -> np.ndarray:
    """For each byte of the XCDR1 payload of ``dt``, the byte of the C layout it comes from.

    Padding bytes of the payload point at index ``dt.itemsize`` (a zero byte appended to the C
    buffer). Valid for final structs of primitives and fixed arrays, which these messages are.

    Returns:
        int array (payload size,).
    """
    index: list[int] = []
    for offset, size in _leaves(dt):
        align = min(size, 8)
        index += [dt.itemsize] * (-len(index) % align)
        index += range(offset, offset + size)
    return np.array(index, dtype=np.intp)


class Codec:
    """One message buffer of one type, with its conversion to and from wire bytes and its CRC.

    ``message`` is a 0-d record array with the C struct's layout; fill its fields with whole-array
    assignments (``message["motor_cmd"]["q"][:29] = q``). One codec per message in flight: it
    reuses its buffers.

    Args:
        dtype: The message's C-layout dtype (:data:`LOW_CMD` or :data:`LOW_STATE`); its last field
            is the ``crc`` word.
    """

    def __init__(self, dtype: np.dtype):
        self.dtype = dtype
        self._gather = cdr_index(dtype)
        self.wire_size = len(XCDR1_LE) + self._gather.size
        data = self._gather < dtype.itemsize
        self._scatter_to, self._scatter_from = self._gather[data], np.flatnonzero(data)
        self._crc_end = dtype.fields["crc"][1]  # type: ignore[index]
        # the C layout plus one zero byte, which the payload's padding bytes are gathered from
        self._buffer = np.zeros(dtype.itemsize + 1, dtype=np.uint8)
        self.message = self._buffer[: dtype.itemsize].view(dtype).reshape(())
        self._wire = np.zeros(self.wire_size, dtype=np.uint8)
        self._wire[: len(XCDR1_LE)] = np.frombuffer(XCDR1_LE, np.uint8)

    @property
    def packed(self) -> np.ndarray:
        """The message's bytes in the C layout (read-only view)."""
        view = self._buffer[: self.dtype.itemsize]
        view.flags.writeable = False
        return view

    def crc(self) -> int:
        """The CRC of the message as it is now (every word before the ``crc`` field)."""
        return crc32_words(self._buffer[: self._crc_end])

    def encode(self) -> bytes:
        """Stamp the CRC into the message and return its wire bytes (header + XCDR1 payload)."""
        self.message["crc"] = crc32_words(self._buffer[: self._crc_end])
        np.take(self._buffer, self._gather, out=self._wire[len(XCDR1_LE):])
        return self._wire.tobytes()

    def decode(self, data: bytes) -> bool:
        """Fill the message from wire bytes; whether its CRC is valid.

        Raises:
            WireFormatError: Not a little-endian XCDR1 payload of this type's size.
        """
        if len(data) < self.wire_size or data[:4] != XCDR1_LE:
            raise WireFormatError(
                f"{_name(self.dtype)} expected as {self.wire_size} bytes of little-endian XCDR1 "
                f"(header {XCDR1_LE.hex()}); got {len(data)} bytes with header {data[:4].hex()}")
        payload = np.frombuffer(data, np.uint8, self.wire_size - 4, 4)
        self._buffer[self._scatter_to] = payload[self._scatter_from]
        return int(self.message["crc"]) == crc32_words(self._buffer[: self._crc_end])


def _name(dt: np.dtype) -> str:
    return "LowCmd_" if dt is LOW_CMD else "LowState_" if dt is LOW_STATE else "message"


def low_cmd_codec() -> Codec:
    """A ``LowCmd_`` buffer and its codec."""
    return Codec(LOW_CMD)


def low_state_codec() -> Codec:
    """A ``LowState_`` buffer and its codec."""
    return Codec(LOW_STATE)
