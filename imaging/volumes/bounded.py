"""Bounded reading of a volume file: sizes checked before allocating, decompression capped.

A header may declare any size; a compressed stream may inflate to any size (a gzip bomb); a
detached data file may be a device. Every reader here:

- checks the declared voxel count x item size against the caller's byte bound before anything
  is allocated (:func:`declared_bytes`);
- reads or inflates into **one preallocated array of exactly the declared size**, feeding the
  decompressor 1 MiB of input at a time and asking it for no more output than still fits
  (:func:`fill_array`): a bomb costs the declared bytes at most, never more, and stops there;
- names the file and what is short when the data end before the header's size.

Text headers (NRRD, MetaImage) are read up to :data:`MAX_HEADER_BYTES`; a gzip stream's own
header fields (the stored file name and comment) up to :data:`MAX_GZIP_FIELD_BYTES`, read in
blocks (:func:`gzip_header_bytes`; Python's ``gzip`` module reads a name byte by byte: a 60 MB
name took 74 s).

Every compressed stream, whatever its codec, may declare at most :data:`MAX_RATIO` times its
compressed bytes: deflate's own largest expansion (gzip, zlib), and the bound ctdrill sets for
bzip2 (whose format allows far more: a few kB inflating to a GiB), so a bomb of any codec is
refused before anything is allocated.
"""

from __future__ import annotations

import bz2
import zlib
from collections.abc import Callable
from typing import IO, Any

import numpy as np

#: Longest text header read (NRRD, MetaImage), bytes; a 3D Slicer segmentation of 500
#: segments has a header of about 400 kB.
MAX_HEADER_BYTES = 1 << 20
#: Compressed input fed per step, bytes.
_CHUNK = 1 << 20
#: Most output asked of the decompressor per step, bytes.
_STEP = 16 << 20
#: Raw bytes read per step when each filled span is handed on (``on_chunk``): small enough
#: that the span is still in the cache when it is measured and hashed.
_CHUNK_STEP = 1 << 20
#: Codecs :func:`fill_array` inflates: gzip (or zlib: both detected by the header), bzip2.
CODECS = ("raw", "gzip", "zlib", "bzip2")
#: Deflate's largest expansion (a run of one byte: 258 bytes per 2 bits), plus header slack:
#: the most any compressed voxel stream may declare per compressed byte (bzip2 included).
MAX_RATIO = 1032
_DEFLATE_SLACK = 1024
#: Longest gzip header field read (FNAME, FCOMMENT; FEXTRA is at most 65535 by the format).
MAX_GZIP_FIELD_BYTES = 64 * 1024

ErrorType = type[Exception]


def _zlib_module() -> Any:
    """zlib-ng (inflates the same streams about twice as fast: bench/bench_volumes.py), else
    the standard zlib."""
    try:
        from zlib_ng import zlib_ng
    except ImportError:  # pragma: no cover - zlib-ng is a dependency
        return zlib
    return zlib_ng


_ZLIB: Any = _zlib_module()
_INFLATE_ERRORS: tuple[type[BaseException], ...] = (
    zlib.error,
    _ZLIB.error,
    OSError,
    EOFError,
    ValueError,
)


def declared_bytes(
    shape: tuple[int, ...],
    itemsize: int,
    *,
    max_bytes: int,
    where: str,
    error: ErrorType,
    field: str = "the header",
) -> int:
    """Bytes of voxel data a header declares, refused beyond ``max_bytes`` or when empty.

    Computed with Python integers (no overflow) before anything is allocated.
    """
    dims = [int(n) for n in shape]
    if any(n < 1 for n in dims):
        raise error(
            f"{where}: {field} declares the size {tuple(dims)}: a volume has at least one "
            "voxel along every axis"
        )
    total = int(itemsize)
    for n in dims:
        total *= n
    if total > max_bytes:
        raise error(
            f"{where}: {field} declares {tuple(dims)} voxels of {itemsize} bytes ({total} bytes), "
            f"more than the {max_bytes} accepted; crop or resample the volume"
        )
    return total


def check_available(
    fh: IO[bytes], *, codec: str, nbytes: int, skip: int, where: str, error: ErrorType
) -> None:
    """Refuse before allocating when the rest of the file cannot hold ``nbytes`` of voxels.

    Raw data must be there byte for byte; a deflate stream (gzip, zlib) expands at most
    1032-fold, so a header declaring more than that of the compressed bytes left lies; a bzip2
    stream is held to the same ratio (:data:`MAX_RATIO`). A gzip stream's header fields are
    checked here too (:func:`gzip_header_bytes`).
    """
    here = fh.tell()
    left = fh.seek(0, 2) - here
    fh.seek(here)
    if codec == "raw":
        holds = left - skip
    elif codec in ("gzip", "zlib", "bzip2"):
        holds = left * MAX_RATIO + _DEFLATE_SLACK - skip
        if codec == "gzip":
            gzip_header_bytes(fh, where=where, error=error)
            fh.seek(here)
    else:
        return
    if codec == "bzip2" and holds < nbytes:
        raise error(
            f"{where}: the header declares {nbytes} bytes of voxel data from {left} bytes of "
            f"bzip2 (more than {MAX_RATIO} times, the most ctdrill inflates); the file is a "
            "decompression bomb or its header lies: save the volume raw or gzip"
        )
    if holds < nbytes:
        raise error(
            f"{where}: the header declares {nbytes} bytes of voxel data, the file holds "
            + (
                f"{max(0, holds)}"
                if codec == "raw"
                else f"{left} compressed bytes (at most {max(0, holds)} once inflated)"
            )
            + "; the file is truncated or its header lies"
        )


def gzip_header_bytes(fh: IO[bytes], *, where: str, error: ErrorType) -> int:
    """Length of the gzip member header at ``fh``'s position (RFC 1952), its fields bounded.

    The stored name and comment are read in blocks up to :data:`MAX_GZIP_FIELD_BYTES` each;
    longer ones are refused (no tool writes a name of 64 kB). The position is left after the
    header.
    """
    head = fh.read(10)
    if len(head) < 10 or head[:2] != b"\x1f\x8b" or head[2] != 8:
        raise error(f"{where}: not a gzip stream (no 1f 8b 08 header); the file is damaged")
    flags = head[3]
    size = 10
    if flags & 0x04:  # FEXTRA
        raw = fh.read(2)
        if len(raw) < 2:
            raise error(
                f"{where}: the gzip header ends inside its extra field; the file is damaged"
            )
        extra = int.from_bytes(raw, "little")
        if len(fh.read(extra)) < extra:
            raise error(
                f"{where}: the gzip header ends inside its extra field; the file is damaged"
            )
        size += 2 + extra
    for bit, name in ((0x08, "file name"), (0x10, "comment")):
        if flags & bit:
            size += _gzip_text_field(fh, name, where, error)
    if flags & 0x02:  # FHCRC
        fh.read(2)
        size += 2
    return size


def _gzip_text_field(fh: IO[bytes], name: str, where: str, error: ErrorType) -> int:
    """Bytes of a zero-terminated gzip header field (its zero included), read in blocks."""
    start = fh.tell()
    seen = 0
    while seen <= MAX_GZIP_FIELD_BYTES:
        block = fh.read(4096)
        if not block:
            raise error(f"{where}: the gzip header's {name} never ends; the file is damaged")
        at = block.find(b"\0")
        if at >= 0:
            fh.seek(start + seen + at + 1)
            return seen + at + 1
        seen += len(block)
    raise error(
        f"{where}: the gzip header's {name} field runs past {MAX_GZIP_FIELD_BYTES} bytes; no "
        "tool writes such a header: the file is damaged or hostile, compress it again"
    )


def gunzip_prefix(fh: IO[bytes], nbytes: int, *, where: str, error: ErrorType) -> bytes:
    """The first ``nbytes`` (or fewer, at the stream's end) of the gzip stream at ``fh``'s
    position, its header fields bounded (:func:`gzip_header_bytes`) and its input read in
    blocks: a header, never the whole stream."""
    gzip_header_bytes(fh, where=where, error=error)
    dec = _ZLIB.decompressobj(-zlib.MAX_WBITS)
    out = b""
    pending = b""
    while len(out) < nbytes:
        if not pending:
            pending = fh.read(64 * 1024)
            if not pending:
                break
        try:
            out += dec.decompress(pending, nbytes - len(out))
        except _INFLATE_ERRORS as exc:
            raise error(f"{where}: the gzip stream cannot be inflated ({exc})") from exc
        pending = dec.unconsumed_tail
        if dec.eof:
            break
    return out


def allocate(
    shape: tuple[int, ...], dtype: np.dtype, *, where: str, error: ErrorType
) -> np.ndarray:
    """``np.empty(shape, dtype)``, a failed allocation named as an input error."""
    try:
        return np.empty(shape, dtype=dtype)
    except MemoryError as exc:
        nbytes = int(np.prod(shape, dtype=object)) * dtype.itemsize
        raise error(
            f"{where}: {nbytes} bytes of voxel data cannot be allocated here; crop or resample "
            "the volume"
        ) from exc


def _decompressor(codec: str) -> Any:
    if codec == "bzip2":
        return bz2.BZ2Decompressor()
    return _ZLIB.decompressobj(zlib.MAX_WBITS | 32)  # gzip or zlib, by the stream's header


def _inflate(
    fh: IO[bytes],
    codec: str,
    out: memoryview,
    skip: int,
    where: str,
    error: ErrorType,
    on_chunk: Callable[[memoryview], None] | None = None,
) -> int:
    """Inflate into ``out`` after dropping ``skip`` bytes; the number of bytes filled."""
    total = skip + len(out)
    pos = 0
    dec = _decompressor(codec)
    pending = b""
    while pos < total:
        if dec.eof:  # the next member of a multi-member stream (pigz, bgzip)
            pending = dec.unused_data + pending or fh.read(_CHUNK)
            if not pending:
                break
            dec = _decompressor(codec)
        try:
            chunk = dec.decompress(pending, min(total - pos, _STEP))
        except _INFLATE_ERRORS as exc:
            raise error(
                f"{where}: the compressed voxel data cannot be decompressed ({exc}); the file is "
                "damaged or not what its header says"
            ) from exc
        pending = dec.unconsumed_tail if codec != "bzip2" else b""
        if not chunk and not pending:
            pending = fh.read(_CHUNK)
            if not pending and (codec != "bzip2" or dec.needs_input):
                break
            continue
        start = max(0, skip - pos)
        if start < len(chunk):
            at = pos + start - skip
            out[at : at + len(chunk) - start] = memoryview(chunk)[start:]  # no copy of a slice
            if on_chunk is not None:
                on_chunk(out[at : at + len(chunk) - start])
        pos += len(chunk)
    if pos >= total and _more_output(dec, pending, fh, codec):
        raise error(
            f"{where}: the compressed data hold more than the {len(out)} bytes of voxel data "
            "the header declares; the file is damaged or its header lies"
        )
    return max(0, pos - skip)


def _more_output(dec: Any, pending: bytes, fh: IO[bytes], codec: str) -> bool:
    """True when the stream inflates to at least one byte more (one bounded step)."""
    for _ in range(4):
        if dec.eof:
            rest = dec.unused_data + pending + fh.read(64)
            return bool(rest.strip(b"\0"))  # zero padding after the stream is tolerated
        try:
            extra = dec.decompress(pending, 1)
        except _INFLATE_ERRORS:
            return True
        if extra:
            return True
        pending = dec.unconsumed_tail if codec != "bzip2" else b""
        if not pending:
            pending = fh.read(_CHUNK)
            if not pending:
                return False
    return False


def fill_array(
    fh: IO[bytes],
    out: np.ndarray,
    *,
    codec: str,
    where: str,
    error: ErrorType,
    skip: int = 0,
    on_chunk: Callable[[memoryview], None] | None = None,
) -> None:
    """Fill the C-contiguous ``out`` with the voxel bytes at ``fh``'s position.

    Parameters
    ----------
    fh : open binary file at the first byte of the data (of the compressed stream).
    out : the preallocated array; exactly ``out.nbytes`` bytes are read.
    codec : ``raw``, ``gzip``, ``zlib`` or ``bzip2``.
    skip : bytes dropped first (after decompression for a compressed stream).
    on_chunk : called with each filled span of ``out`` (a byte view), in order, as soon as
        it is filled (e.g. :class:`.identity.VoxelDigest.feed`); the spans cover ``out``.
    """
    if not out.flags.c_contiguous:  # a reshape would fill a copy
        raise ValueError("fill_array needs a C-contiguous array")
    view = out.reshape(-1).view(np.uint8).data
    if codec == "raw":
        if skip:
            fh.seek(skip, 1)
        got = 0
        step = _CHUNK_STEP if on_chunk is not None else len(view)
        while got < len(view):
            n = fh.readinto(view[got : got + step])  # type: ignore[attr-defined]
            if not n:
                break
            if on_chunk is not None:
                on_chunk(view[got : got + n])
            got += n
    elif codec in CODECS:
        got = _inflate(fh, codec, view, skip, where, error, on_chunk)
    else:
        raise error(f"{where}: encoding {codec!r} is not read; save the volume raw or gzip")
    if got < len(view):
        raise error(
            f"{where}: the header declares {len(view)} bytes of voxel data, the file holds "
            f"{got}; the file is truncated or its header lies"
        )


def read_text_header(fh: IO[bytes], *, where: str, error: ErrorType, end: bytes) -> tuple[str, int]:
    """The text header up to and including the first line starting with ``end`` (or a blank
    line when ``end`` is ``b""``), and the byte offset just past it.

    The header may be the whole file (a detached header): then it ends at the end of file.
    """
    head = fh.read(MAX_HEADER_BYTES + 1)
    offset = 0
    lines: list[bytes] = []
    for raw in head.splitlines(keepends=True):
        if not raw.endswith(b"\n") and offset + len(raw) > MAX_HEADER_BYTES:
            break
        offset += len(raw)
        line = raw.rstrip(b"\r\n")
        if end == b"" and line == b"":
            return _decode(lines, where, error), offset
        lines.append(line)
        if end and line.lstrip().startswith(end):
            return _decode(lines, where, error), offset
    if len(head) > MAX_HEADER_BYTES:
        raise error(
            f"{where}: the header runs past {MAX_HEADER_BYTES} bytes without its end; this is "
            "not a volume header ctdrill reads"
        )
    return _decode(lines, where, error), offset


def _decode(lines: list[bytes], where: str, error: ErrorType) -> str:
    try:
        return b"\n".join(lines).decode("latin-1")
    except UnicodeDecodeError as exc:  # pragma: no cover - latin-1 decodes every byte
        raise error(f"{where}: the header is not text") from exc
