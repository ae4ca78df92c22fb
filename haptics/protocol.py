"""The host <-> device binary protocol (docs/protocol.md): pure encode/decode, no I/O.

A frame on the wire is ``COBS(header + body + crc32c) + b"\\x00"``:

* header, 18 bytes little-endian: ``version u8, type u8, seq u32, session u32, time_us u64``
  (the sender's sequence number, the session nonce the device chose at HELLO, the device
  clock in microseconds for device->host frames and 0 from the host, which the device checks);
* body: the message's fixed little-endian layout (``PROFILE_CHUNK`` carries 1..16 rows);
* ``crc32c``: CRC-32C (Castagnoli; check value ``0xE3069283`` for ``b"123456789"``) over
  header + body, appended little-endian.

Sequence numbers compare in serial-number arithmetic (RFC 1982, 32 bits: :func:`seq_after`),
so they wrap from 0xFFFFFFFF to 0.

A decoded frame is at most :data:`MAX_DECODED` bytes. The messages are in
:mod:`ctdrill.haptics.messages`; this module only encodes and decodes. The profile table is
protected as a whole by a CRC-32 (zlib/IEEE 802.3, check ``0xCBF43926``) over the
``PROFILE_BEGIN`` body followed by every row's ``s0, s1, s2`` float32 triplet in index order.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass, fields

from ctdrill.haptics.codes import (
    DEVICE_TYPES,
    HOST_TYPES,
    DeviceState,
    Fault,
    MsgType,
    NakReason,
    OperatorKind,
)
from ctdrill.haptics.framing import (
    ChecksumError,
    FramingError,
    MessageError,
    ProtocolError,
    UnknownTypeError,
    VersionError,
    cobs_decode,
    cobs_encode,
    crc32,
    crc32c,
)
from ctdrill.haptics.messages import (
    FIXED,
    MAX_CHUNK_ROWS,
    PROTOCOL_VERSION,
    ROW,
    Ack,
    Arm,
    Disarm,
    FaultReport,
    Heartbeat,
    Hello,
    Limits,
    Message,
    Nak,
    ProfileBegin,
    ProfileChunk,
    ProfileEnd,
    SimOperator,
    SimReset,
    Stop,
    Telemetry,
    Version,
)

HEADER = struct.Struct("<BBIIQ")
CRC = struct.Struct("<I")
#: Largest decoded frame (header + body + crc), bytes; COBS adds at most 2 more, then 0x00.
MAX_DECODED = 254


@dataclass(frozen=True)
class Packet:
    """A decoded frame: header fields and the message."""

    seq: int
    session: int
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


def encode(message: Message, *, seq: int, session: int = 0, time_us: int = 0) -> bytes:
    """One frame on the wire: ``COBS(header + body + crc32c) + b"\\x00"``.

    ``seq`` (u32) is the sender's sequence number, ``session`` the session nonce (0 before
    HELLO), ``time_us`` the device clock (0 from the host).
    """
    try:
        header = HEADER.pack(PROTOCOL_VERSION, message.TYPE, seq, session, time_us)
    except struct.error as exc:
        raise MessageError(f"{message.TYPE.name}: header field out of range ({exc})") from exc
    raw = header + _body(message)
    raw += CRC.pack(crc32c(raw))
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
    if len(raw) > MAX_DECODED:
        raise FramingError(f"frame of {len(raw)} decoded bytes exceeds {MAX_DECODED}")
    if len(raw) < HEADER.size + CRC.size:
        raise FramingError(f"frame of {len(raw)} bytes is shorter than header + crc")
    (crc,) = CRC.unpack_from(raw, len(raw) - CRC.size)
    if crc != crc32c(raw[: -CRC.size]):
        raise ChecksumError("CRC-32C mismatch")
    version, mtype, seq, session, time_us = HEADER.unpack_from(raw)
    if version != PROTOCOL_VERSION:
        raise VersionError(f"protocol version {version}, expected {PROTOCOL_VERSION}")
    header = (mtype, seq, session)
    body = raw[HEADER.size : -CRC.size]
    message: Message
    if mtype == MsgType.PROFILE_CHUNK:
        count = body[2] if len(body) >= ProfileChunk.FMT.size else -1
        if not 1 <= count <= MAX_CHUNK_ROWS or len(body) != 3 + count * ROW.size:
            raise MessageError(
                f"PROFILE_CHUNK body of {len(body)} bytes (1..{MAX_CHUNK_ROWS} rows of "
                f"{ROW.size} bytes after 3)",
                header=header,
            )
        (first,) = struct.unpack_from("<H", body)
        rows = tuple(ROW.unpack_from(body, 3 + i * ROW.size) for i in range(count))
        message = ProfileChunk(first, rows)
    else:
        cls = FIXED.get(mtype)
        if cls is None:
            raise UnknownTypeError(f"unknown message type 0x{mtype:02x}", header=header)
        if len(body) != cls.FMT.size:
            raise MessageError(
                f"{MsgType(mtype).name} body of {len(body)} bytes, expected {cls.FMT.size}",
                header=header,
            )
        message = cls(*cls.FMT.unpack(body))
    return Packet(seq=seq, session=session, time_us=time_us, message=message)


def seq_after(seq: int, last: int) -> bool:
    """``seq`` comes after ``last`` in 32-bit serial-number arithmetic (RFC 1982): ahead by
    1 .. 2^31 - 1 modulo 2^32 (so 0 comes after 0xFFFFFFFF)."""
    return 0 < (seq - last) & 0xFFFFFFFF < 0x80000000


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
    "DEVICE_TYPES",
    "HEADER",
    "HOST_TYPES",
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
    "crc32",
    "crc32c",
    "decode",
    "encode",
    "profile_crc32",
    "seq_after",
]
