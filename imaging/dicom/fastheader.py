"""A minimal reader of the header tags the loader needs, for uncompressed little-endian files.

pydicom converts every element it reads (~0.8 ms per CT header here); this walks the element
stream of a Part 10 file (128-byte preamble, ``DICM``, explicit-VR file meta, then an Explicit or
Implicit VR Little Endian dataset), keeps the raw bytes of a fixed set of top-level tags, skips
everything else (sequences of defined or undefined length included) and stops at PixelData,
whose value offset it returns. Anything unexpected returns None and the caller falls back to
pydicom, so this is an accelerator, never a second source of truth: the tests check that both
paths give identical headers on every real and synthetic file.
"""

from __future__ import annotations

import os
import stat
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ctdrill.imaging.dicom.slice_header import IMPLICIT_VR_LITTLE_ENDIAN, NATIVE_SYNTAXES

_LONG_VRS = frozenset(
    {b"OB", b"OW", b"OF", b"OD", b"OL", b"OV", b"UN", b"SQ", b"UC", b"UR", b"UT", b"SV", b"UV"}
)
_PIXEL_DATA = 0x7FE00010
_ITEM = 0xFFFEE000
_ITEM_END = 0xFFFEE00D
_SEQ_END = 0xFFFEE0DD
_UNDEFINED = 0xFFFFFFFF

#: tag -> (keyword, VR used when the file is implicit VR)
TAGS: dict[int, tuple[str, str]] = {
    0x00041220: ("DirectoryRecordSequence", "SQ"),
    0x00080008: ("ImageType", "CS"),
    0x00080016: ("SOPClassUID", "UI"),
    0x00080060: ("Modality", "CS"),
    0x00080070: ("Manufacturer", "LO"),
    0x00081030: ("StudyDescription", "LO"),
    0x0008103E: ("SeriesDescription", "LO"),
    0x00081090: ("ManufacturerModelName", "LO"),
    0x00180050: ("SliceThickness", "DS"),
    0x00180060: ("KVP", "DS"),
    0x00180088: ("SpacingBetweenSlices", "DS"),
    0x00181120: ("GantryDetectorTilt", "DS"),
    0x00181210: ("ConvolutionKernel", "SH"),
    0x0020000E: ("SeriesInstanceUID", "UI"),
    0x00200052: ("FrameOfReferenceUID", "UI"),
    0x00200032: ("ImagePositionPatient", "DS"),
    0x00200037: ("ImageOrientationPatient", "DS"),
    0x00280002: ("SamplesPerPixel", "US"),
    0x00280004: ("PhotometricInterpretation", "CS"),
    0x00280008: ("NumberOfFrames", "IS"),
    0x00280010: ("Rows", "US"),
    0x00280011: ("Columns", "US"),
    0x00280030: ("PixelSpacing", "DS"),
    0x00280100: ("BitsAllocated", "US"),
    0x00280101: ("BitsStored", "US"),
    0x00280103: ("PixelRepresentation", "US"),
    0x00280120: ("PixelPaddingValue", "xs"),
    0x00280121: ("PixelPaddingRangeLimit", "xs"),
    0x00281052: ("RescaleIntercept", "DS"),
    0x00281053: ("RescaleSlope", "DS"),
    0x00281054: ("RescaleType", "LO"),
    0x00282110: ("LossyImageCompression", "CS"),
}
_TRAILING_ONLY = frozenset({"LO", "SH", "LT", "ST", "UT"})
_INT_FORMATS = {"US": "H", "SS": "h", "UL": "I", "SL": "i"}
#: Bytes read first; most CT headers are shorter (more is read when needed).
_FIRST_READ = 16384


class _Malformed(Exception):
    """Something this reader does not handle: fall back to pydicom."""


class HeaderCorruptError(Exception):
    """The header cannot be right (an element runs past the end of the file): do not parse on.

    pydicom would try to allocate the declared length (a memory bomb), so no fallback.
    """


@dataclass(frozen=True)
class FastHeader:
    """What :func:`read_fast_header` found."""

    tags: dict[str, Any]
    transfer_syntax: str
    implicit: bool
    pixel_offset: int | None  # None: encapsulated (compressed) pixel data
    pixel_length: int | None  # declared value length of native PixelData, bytes
    has_pixels: bool
    file_size: int


class _NeedMore(Exception):
    """The header continues beyond the bytes read so far."""


def _need(buf: bytes, size: int, end: int) -> None:
    """Make sure ``buf[:end]`` exists: corrupt if past the file, read more if past ``buf``."""
    if end > size:
        raise HeaderCorruptError("a header element runs past the end of the file (truncated)")
    if end > len(buf):
        raise _NeedMore


def _element(buf: bytes, size: int, pos: int, implicit: bool) -> tuple[int, bytes, int, int]:
    """(tag, vr, value start, length) of the element at ``pos``."""
    _need(buf, size, pos + 8)
    group, elem = struct.unpack_from("<HH", buf, pos)
    tag = (group << 16) | elem
    if implicit or group == 0xFFFE:
        (length,) = struct.unpack_from("<I", buf, pos + 4)
        return tag, b"", pos + 8, length
    vr = buf[pos + 4 : pos + 6]
    if vr in _LONG_VRS:
        _need(buf, size, pos + 12)
        (length,) = struct.unpack_from("<I", buf, pos + 8)
        return tag, vr, pos + 12, length
    if not vr.isalpha():
        raise _Malformed
    (length,) = struct.unpack_from("<H", buf, pos + 6)
    return tag, vr, pos + 8, length


def _skip_undefined(buf: bytes, size: int, pos: int, implicit: bool) -> int:
    """Skip the items of an undefined-length sequence starting at ``pos``; return the end.

    Iterative (an explicit stack of open sequences and items), so a file nesting sequences
    thousands deep costs time linear in its size and no recursion.
    """
    # each entry: (inside an item? else inside a sequence, implicit VR at that level)
    stack: list[tuple[bool, bool]] = [(False, implicit)]
    while stack:
        in_item, level_implicit = stack[-1]
        if not in_item:
            tag, _, start, length = _element(buf, size, pos, True)
            if tag == _SEQ_END:
                stack.pop()
                pos = start
                continue
            if tag != _ITEM:
                raise _Malformed
            if length != _UNDEFINED:
                pos = start + length
                if pos > size:
                    raise HeaderCorruptError("a sequence item runs past the end of the file")
                continue
            stack.append((True, level_implicit))
            pos = start
            continue
        # elements of an undefined-length item, up to its delimiter
        tag, vr, start, length = _element(buf, size, pos, level_implicit)
        if tag == _ITEM_END:
            stack.pop()
            pos = start
            continue
        if length == _UNDEFINED:
            stack.append((False, level_implicit or vr == b"UN"))
            pos = start
            continue
        pos = start + length
        if pos > size:
            raise HeaderCorruptError("an element runs past the end of the file")
    return pos


def _decode(raw: bytes, vr: str, pixel_rep: int) -> Any:
    if vr == "xs":
        vr = "SS" if pixel_rep else "US"
    if vr in _INT_FORMATS:
        fmt = _INT_FORMATS[vr]
        n = len(raw) // struct.calcsize(fmt)
        vals = struct.unpack_from(f"<{n}{fmt}", raw)
        return vals[0] if n == 1 else list(vals)
    text = raw.decode("latin-1")
    text = text.rstrip(" \x00") if vr in _TRAILING_ONLY else text.strip(" \x00")
    if vr in ("LT", "ST", "UT"):
        return text
    parts = text.split("\\")
    if vr not in _TRAILING_ONLY:
        parts = [p.strip(" \x00") for p in parts]
    return parts[0] if len(parts) == 1 else parts


def read_fast_header(path: Path) -> FastHeader | None:
    """Header of a Part 10 little-endian file without pydicom, or None to fall back.

    Reads a 16 KiB prefix first and more only when the header is longer.

    Raises
    ------
    HeaderCorruptError
        A header element declares more bytes than the file holds.
    """
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)  # a FIFO never blocks the open
    except OSError:
        return None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):  # swapped since it was listed: pydicom's path says so
            return None
        size = st.st_size
        chunk = _FIRST_READ
        while True:
            buf = os.pread(fd, min(chunk, size), 0)
            try:
                return _parse(buf, size)
            except _NeedMore:
                chunk *= 4
    except (_Malformed, struct.error, ValueError, OSError, UnicodeDecodeError):
        return None
    finally:
        os.close(fd)


def _parse(buf: bytes, size: int) -> FastHeader | None:
    if size < 132 or buf[128:132] != b"DICM":
        return None
    pos = 132
    ts = ""
    while pos + 8 <= size:
        _need(buf, size, pos + 2)
        if struct.unpack_from("<H", buf, pos)[0] != 0x0002:
            break
        tag, _, start, length = _element(buf, size, pos, False)
        if length == _UNDEFINED:
            return None
        _need(buf, size, start + length)
        if tag == 0x00020010:
            ts = buf[start : start + length].decode("ascii").strip(" \x00")
        pos = start + length
    if ts not in NATIVE_SYNTAXES:
        return None
    implicit = ts == IMPLICIT_VR_LITTLE_ENDIAN
    raw: dict[int, tuple[str, bytes]] = {}
    offset: int | None = None
    pixel_length: int | None = None
    has_pixels = False
    while pos + 8 <= size:
        tag, vr, start, length = _element(buf, size, pos, implicit)
        if tag == _PIXEL_DATA:
            has_pixels = length != 0
            if length != _UNDEFINED:
                offset, pixel_length = start, length
            break
        if tag in TAGS:
            keyword, default_vr = TAGS[tag]
            vr_s = default_vr if implicit or (default_vr == "xs" and vr in (b"OB", b"OW")) else ""
            vr_s = vr_s or vr.decode("ascii")
            value = b""
            if length != _UNDEFINED:
                _need(buf, size, start + length)
                value = buf[start : start + length]
            raw[tag] = (vr_s, value)
        if length == _UNDEFINED:
            pos = _skip_undefined(buf, size, start, implicit or vr == b"UN")
        else:
            pos = start + length
        if pos > size:
            raise HeaderCorruptError("a header element runs past the end of the file")
    else:
        if pos != size:
            raise HeaderCorruptError("the file ends inside a header element (truncated)")
    out: dict[str, Any] = {}
    pixel_rep = 0
    if 0x00280103 in raw:
        pixel_rep = int(_decode(raw[0x00280103][1], "US", 0))
    for tag, (vr_s, value) in raw.items():
        keyword = TAGS[tag][0]
        if vr_s == "SQ":
            out[keyword] = []
            continue
        if not value:
            continue
        out[keyword] = _decode(value, vr_s, pixel_rep)
    return FastHeader(out, ts, implicit, offset, pixel_length, has_pixels, size)
