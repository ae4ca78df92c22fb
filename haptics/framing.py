"""Byte-level framing of the device protocol: COBS, CRC-32C (frames), CRC-32 (tables), typed errors.

See :mod:`ctdrill.haptics.protocol` for the frame layout and docs/protocol.md for the specification.
"""

from __future__ import annotations

import zlib

from ctdrill.haptics.errors import HapticsInputError


class ProtocolError(HapticsInputError):
    """A frame that cannot be accepted; the message says what is wrong with it.

    ``header`` is ``(type, seq, session)`` when the frame's header could be read (its CRC-32C
    and version are right), else None.
    """

    def __init__(self, message: str, *, header: tuple[int, int, int] | None = None) -> None:
        super().__init__(message)
        self.header = header


class FramingError(ProtocolError):
    """Bad COBS encoding or a frame of impossible length (longer than 254 decoded bytes)."""


class ChecksumError(ProtocolError):
    """The frame's CRC-32C does not match its content."""


class MessageError(ProtocolError):
    """Well-framed bytes that are not a valid message (version, type or body length)."""


class UnknownTypeError(MessageError):
    """A message type this protocol version does not define."""


class VersionError(MessageError):
    """A frame of another protocol version."""


def _crc32c_table() -> tuple[int, ...]:
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0x82F63B78 if crc & 1 else crc >> 1
        table.append(crc)
    return tuple(table)


_CRC32C = _crc32c_table()


def crc32c(data: bytes) -> int:
    """CRC-32C (Castagnoli, iSCSI: poly 0x1EDC6F41 reflected, init and final XOR 0xFFFFFFFF);
    ``b"123456789"`` -> 0xE3069283."""
    crc = 0xFFFFFFFF
    table = _CRC32C
    for byte in data:
        crc = (crc >> 8) ^ table[(crc ^ byte) & 0xFF]
    return crc ^ 0xFFFFFFFF


def crc32(data: bytes, value: int = 0) -> int:
    """CRC-32 (IEEE 802.3, as zlib); ``b"123456789"`` -> 0xCBF43926."""
    return zlib.crc32(data, value) & 0xFFFFFFFF


def cobs_encode(data: bytes) -> bytes:
    """Consistent-overhead byte stuffing: the result has no zero byte."""
    out = bytearray()
    block = bytearray()
    for byte in data:
        if byte == 0:
            out.append(len(block) + 1)
            out += block
            block.clear()
        else:
            block.append(byte)
            if len(block) == 254:
                out.append(255)
                out += block
                block.clear()
    out.append(len(block) + 1)
    out += block
    return bytes(out)


def cobs_decode(data: bytes) -> bytes:
    """Inverse of :func:`cobs_encode`; raises :class:`FramingError` on malformed input."""
    out = bytearray()
    i, n = 0, len(data)
    if n == 0:
        raise FramingError("empty frame between delimiters")
    while i < n:
        code = data[i]
        if code == 0:
            raise FramingError(f"COBS: zero byte inside a frame at offset {i}")
        end = i + code
        if end > n:
            raise FramingError(f"COBS: block at offset {i} runs past the frame end")
        block = data[i + 1 : end]
        if 0 in block:
            raise FramingError("COBS: zero byte inside a frame")
        out += block
        i = end
        if code < 255 and i < n:
            out.append(0)
    return bytes(out)
