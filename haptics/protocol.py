"""The host <-> device binary protocol (docs/protocol.md): pure encode/decode, no I/O.

A frame on the wire is ``COBS(header + body + crc16) + b"\\x00"``:

* header, 12 bytes little-endian: ``version u8, type u8, seq u16, time_us u64`` (device clock
  in microseconds for device->host frames, 0 from the host);
* body: the message's fixed little-endian layout (``PROFILE_CHUNK`` carries 1..16 rows);
* ``crc16``: CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, xorout 0; check value
  ``0x29B1`` for ``b"123456789"``) over header + body, appended little-endian.

A decoded frame is at most :data:`MAX_DECODED` bytes. The profile table is protected as a whole by
a CRC-32 (zlib/IEEE 802.3, check ``0xCBF43926``) over the ``PROFILE_BEGIN`` body followed by every
row's ``s0, s1, s2`` float32 triplet in index order.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass, fields
from typing import Any, ClassVar

from ctdrill.haptics.codes import DeviceState, Fault, MsgType, NakReason, OperatorKind
from ctdrill.haptics.framing import (
    ChecksumError,
    FramingError,
    MessageError,
    ProtocolError,
    UnknownTypeError,
    VersionError,
    cobs_decode,
    cobs_encode,
    crc16_ccitt_false,
    crc32,
)

PROTOCOL_VERSION = 1
HEADER = struct.Struct("<BBHQ")
CRC = struct.Struct("<H")
#: Largest decoded frame (header + body + crc), bytes; COBS adds at most 2 more, then 0x00.
MAX_DECODED = 254
#: Rows per PROFILE_CHUNK.
MAX_CHUNK_ROWS = 16
ROW = struct.Struct("<fff")


# ---------------------------------------------------------------- messages


@dataclass(frozen=True)
class Hello:
    """host->device: open a session; the device answers VERSION then LIMITS."""

    TYPE: ClassVar[MsgType] = MsgType.HELLO
    FMT: ClassVar[struct.Struct] = struct.Struct("<B")
    protocol_version: int = PROTOCOL_VERSION


@dataclass(frozen=True)
class Version:
    """device->host: protocol and firmware version, control tick rate."""

    TYPE: ClassVar[MsgType] = MsgType.VERSION
    FMT: ClassVar[struct.Struct] = struct.Struct("<BBBBI")
    protocol_version: int
    fw_major: int
    fw_minor: int
    fw_patch: int
    tick_rate_hz: int


@dataclass(frozen=True)
class Limits:
    """device->host: the limits the device enforces."""

    TYPE: ClassVar[MsgType] = MsgType.LIMITS
    FMT: ClassVar[struct.Struct] = struct.Struct("<fffHHff")
    peak_force_n: float
    continuous_force_n: float
    thermal_budget_n2_s: float
    watchdog_ms: int
    max_profile_steps: int
    travel_min_mm: float
    travel_max_mm: float


@dataclass(frozen=True)
class ProfileBegin:
    """host->device: start a profile upload (discards any previous table, disarms)."""

    TYPE: ClassVar[MsgType] = MsgType.PROFILE_BEGIN
    FMT: ClassVar[struct.Struct] = struct.Struct("<Hfffff")
    n_steps: int
    depth_step_mm: float
    ke_per_mm_s: float
    f1_hz: float
    f2_hz: float
    stop_depth_mm: float


@dataclass(frozen=True)
class ProfileChunk:
    """host->device: rows ``first_index ..`` of the table, each ``(s0_n, s1_n, s2_n)``."""

    TYPE: ClassVar[MsgType] = MsgType.PROFILE_CHUNK
    FMT: ClassVar[struct.Struct] = struct.Struct("<HB")
    first_index: int
    rows: tuple[tuple[float, float, float], ...]


@dataclass(frozen=True)
class ProfileEnd:
    """host->device: end of upload with the table's CRC-32; ACK if complete and intact."""

    TYPE: ClassVar[MsgType] = MsgType.PROFILE_END
    FMT: ClassVar[struct.Struct] = struct.Struct("<HI")
    n_steps: int
    crc32: int


@dataclass(frozen=True)
class Arm:
    """host->device: start rendering (clears a latched safe state)."""

    TYPE: ClassVar[MsgType] = MsgType.ARM
    FMT: ClassVar[struct.Struct] = struct.Struct("<")


@dataclass(frozen=True)
class Disarm:
    """host->device: zero force, back to idle."""

    TYPE: ClassVar[MsgType] = MsgType.DISARM
    FMT: ClassVar[struct.Struct] = struct.Struct("<")


@dataclass(frozen=True)
class Heartbeat:
    """host->device: keeps the watchdog fed (any valid host frame does)."""

    TYPE: ClassVar[MsgType] = MsgType.HEARTBEAT
    FMT: ClassVar[struct.Struct] = struct.Struct("<")


@dataclass(frozen=True)
class Stop:
    """host->device: emergency stop; the device latches its safe state."""

    TYPE: ClassVar[MsgType] = MsgType.STOP
    FMT: ClassVar[struct.Struct] = struct.Struct("<")


@dataclass(frozen=True)
class SimOperator:
    """host->emulator: the simulated hand (``PUSH`` force N, or ``FEED`` mm/s)."""

    TYPE: ClassVar[MsgType] = MsgType.SIM_OPERATOR
    FMT: ClassVar[struct.Struct] = struct.Struct("<Bf")
    kind: int
    value: float


@dataclass(frozen=True)
class SimReset:
    """host->emulator: simulate a power-cycle reset of the device."""

    TYPE: ClassVar[MsgType] = MsgType.SIM_RESET
    FMT: ClassVar[struct.Struct] = struct.Struct("<")


@dataclass(frozen=True)
class Telemetry:
    """device->host, every 1 ms: the renderer's state at tick ``tick``."""

    TYPE: ClassVar[MsgType] = MsgType.TELEMETRY
    FMT: ClassVar[struct.Struct] = struct.Struct("<IfffffBHH")
    tick: int
    master_mm: float
    drill_mm: float
    velocity_mm_s: float
    force_cmd_n: float
    force_est_n: float
    state: int
    faults: int
    overruns: int


@dataclass(frozen=True)
class FaultReport:
    """device->host: sent once when fault flags are raised."""

    TYPE: ClassVar[MsgType] = MsgType.FAULT
    FMT: ClassVar[struct.Struct] = struct.Struct("<HB")
    faults: int
    state: int


@dataclass(frozen=True)
class Ack:
    """device->host: command ``(acked_type, acked_seq)`` accepted."""

    TYPE: ClassVar[MsgType] = MsgType.ACK
    FMT: ClassVar[struct.Struct] = struct.Struct("<BH")
    acked_type: int
    acked_seq: int


@dataclass(frozen=True)
class Nak:
    """device->host: command refused, with a :class:`NakReason`."""

    TYPE: ClassVar[MsgType] = MsgType.NAK
    FMT: ClassVar[struct.Struct] = struct.Struct("<BHB")
    acked_type: int
    acked_seq: int
    reason: int


Message = (
    Hello
    | Version
    | Limits
    | ProfileBegin
    | ProfileChunk
    | ProfileEnd
    | Arm
    | Disarm
    | Heartbeat
    | Stop
    | SimOperator
    | SimReset
    | Telemetry
    | FaultReport
    | Ack
    | Nak
)

_FIXED: dict[int, Any] = {
    cls.TYPE: cls
    for cls in (
        Hello,
        Version,
        Limits,
        ProfileBegin,
        ProfileEnd,
        Arm,
        Disarm,
        Heartbeat,
        Stop,
        SimOperator,
        SimReset,
        Telemetry,
        FaultReport,
        Ack,
        Nak,
    )
}


@dataclass(frozen=True)
class Packet:
    """A decoded frame: header fields and the message."""

    seq: int
    time_us: int
    message: Message


# ---------------------------------------------------------------- encode / decode


def _body(message: Message) -> bytes:
    if isinstance(message, ProfileChunk):
        if not 1 <= len(message.rows) <= MAX_CHUNK_ROWS:
            raise MessageError(f"PROFILE_CHUNK carries 1..{MAX_CHUNK_ROWS} rows")
        head = ProfileChunk.FMT.pack(message.first_index, len(message.rows))
        return head + b"".join(ROW.pack(*row) for row in message.rows)
    values = [getattr(message, f.name) for f in fields(message)]
    try:
        return message.FMT.pack(*values)
    except struct.error as exc:
        raise MessageError(f"{message.TYPE.name}: field out of range ({exc})") from exc


def encode(message: Message, *, seq: int, time_us: int = 0) -> bytes:
    """One frame on the wire: ``COBS(header + body + crc16) + b"\\x00"``.

    ``seq`` is taken modulo 2**16; ``time_us`` is the device clock (0 from the host).
    """
    raw = HEADER.pack(PROTOCOL_VERSION, message.TYPE, seq & 0xFFFF, time_us) + _body(message)
    raw += CRC.pack(crc16_ccitt_false(raw))
    if len(raw) > MAX_DECODED:
        raise MessageError(f"{message.TYPE.name}: frame of {len(raw)} bytes exceeds {MAX_DECODED}")
    return cobs_encode(raw) + b"\x00"


def decode(frame: bytes) -> Packet:
    """Decode one frame (COBS bytes without the 0x00 delimiter).

    Raises
    ------
    FramingError, ChecksumError, MessageError
        Whatever is wrong with it; nothing else escapes for any input.
    """
    if len(frame) > MAX_DECODED + 2:
        raise FramingError(f"frame of {len(frame)} bytes exceeds {MAX_DECODED + 2}")
    raw = cobs_decode(frame)
    if len(raw) < HEADER.size + CRC.size:
        raise FramingError(f"frame of {len(raw)} bytes is shorter than header + crc")
    (crc,) = CRC.unpack_from(raw, len(raw) - CRC.size)
    if crc != crc16_ccitt_false(raw[: -CRC.size]):
        raise ChecksumError("CRC-16 mismatch")
    version, mtype, seq, time_us = HEADER.unpack_from(raw)
    if version != PROTOCOL_VERSION:
        raise VersionError(f"protocol version {version}, expected {PROTOCOL_VERSION}")
    body = raw[HEADER.size : -CRC.size]
    message: Message
    if mtype == MsgType.PROFILE_CHUNK:
        if len(body) < ProfileChunk.FMT.size:
            raise MessageError("PROFILE_CHUNK body too short")
        first, count = ProfileChunk.FMT.unpack_from(body)
        if not 1 <= count <= MAX_CHUNK_ROWS or len(body) != 3 + count * ROW.size:
            raise MessageError(f"PROFILE_CHUNK body of {len(body)} bytes for {count} rows")
        rows = tuple(ROW.unpack_from(body, 3 + i * ROW.size) for i in range(count))
        message = ProfileChunk(first, rows)
    else:
        cls = _FIXED.get(mtype)
        if cls is None:
            raise UnknownTypeError(f"unknown message type 0x{mtype:02x}")
        if len(body) != cls.FMT.size:
            raise MessageError(
                f"{MsgType(mtype).name} body of {len(body)} bytes, expected {cls.FMT.size}"
            )
        message = cls(*cls.FMT.unpack(body))
    return Packet(seq=seq, time_us=time_us, message=message)


def profile_crc32(begin: ProfileBegin, rows: Sequence[tuple[float, float, float]]) -> int:
    """CRC-32 of the whole table: the PROFILE_BEGIN body then every row as 3 float32."""
    value = crc32(_body(begin))
    for row in rows:
        value = crc32(ROW.pack(*row), value)
    return value


class FrameReader:
    """Splits a byte stream on 0x00 and decodes each frame.

    Bytes are consumed in one pass; a run longer than any valid frame is dropped up to the next
    delimiter and reported once as a :class:`FramingError`, so garbage can never grow the buffer
    or stall the reader.
    """

    def __init__(self) -> None:
        self._buf = bytearray()
        self._overflow = False

    def feed(self, data: bytes) -> list[Packet | ProtocolError]:
        """Decoded packets and the errors of rejected frames, in stream order."""
        out: list[Packet | ProtocolError] = []
        start = 0
        while True:
            end = data.find(b"\x00", start)
            if end < 0:
                self._append(data[start:], out)
                return out
            self._append(data[start:end], out)
            if self._overflow:
                self._overflow = False
            elif self._buf:
                try:
                    out.append(decode(bytes(self._buf)))
                except ProtocolError as exc:
                    out.append(exc)
            self._buf.clear()
            start = end + 1

    def _append(self, chunk: bytes, out: list[Packet | ProtocolError]) -> None:
        if self._overflow:
            return
        self._buf += chunk
        if len(self._buf) > MAX_DECODED + 2:
            self._buf.clear()
            self._overflow = True
            out.append(FramingError("run of bytes longer than any frame; dropped"))


__all__ = [
    "CRC",
    "HEADER",
    "MAX_CHUNK_ROWS",
    "MAX_DECODED",
    "PROTOCOL_VERSION",
    "ROW",
    "Ack",
    "Arm",
    "ChecksumError",
    "DeviceState",
    "Disarm",
    "Fault",
    "FaultReport",
    "FrameReader",
    "FramingError",
    "Heartbeat",
    "Hello",
    "Limits",
    "Message",
    "MessageError",
    "MsgType",
    "Nak",
    "NakReason",
    "OperatorKind",
    "Packet",
    "ProfileBegin",
    "ProfileChunk",
    "ProfileEnd",
    "ProtocolError",
    "SimOperator",
    "SimReset",
    "Stop",
    "Telemetry",
    "UnknownTypeError",
    "Version",
    "VersionError",
    "cobs_decode",
    "cobs_encode",
    "crc16_ccitt_false",
    "crc32",
    "decode",
    "encode",
    "profile_crc32",
]
