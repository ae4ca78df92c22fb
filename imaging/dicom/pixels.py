"""Stored pixel values of one plane, and their conversion to HU.

Uncompressed little-endian planes are read straight from the file at the recorded byte offset.
Everything else goes through pydicom's decoders with an explicitly chosen plugin
(:func:`decoder_plugin_for`), so that it is always known which library decoded a syntax (Pillow,
pulled in by vtk, is never used). Bits above BitsStored are masked (unsigned) or sign-extended
(signed) here, whatever the decoder did.
"""

from __future__ import annotations

import itertools
import struct
import warnings
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ctdrill.imaging.dicom.discovery import SliceHeader
from ctdrill.imaging.errors import ImagingInputError
from ctdrill.safeio import open_regular

if TYPE_CHECKING:  # pydicom is imported only for compressed planes (0.2 s of a start-up)
    from pydicom.dataset import Dataset

_ITEM = 0xFFFEE000


class PixelInputError(ImagingInputError):
    """Pixel data that cannot be read or decoded."""


def get_decoder(uid: str) -> Any:
    """pydicom's pixel decoder for the transfer syntax ``uid`` (pydicom is imported here, for
    the first compressed plane)."""
    from pydicom.pixels import get_decoder as pydicom_decoder

    return pydicom_decoder(uid)


def decoder_plugin_for(transfer_syntax: str) -> str:
    """The pydicom decoding plugin used for ``transfer_syntax`` ("" for native syntaxes).

    JPEG (lossless, baseline, extended), JPEG-LS, JPEG 2000 and RLE go to ``pylibjpeg``
    (pylibjpeg-libjpeg, pylibjpeg-openjpeg, pylibjpeg-rle); RLE falls back to pydicom's own
    decoder when pylibjpeg is missing.
    """
    from pydicom.uid import UID

    uid = UID(transfer_syntax)
    try:
        compressed = uid.is_compressed
    except ValueError as exc:
        raise PixelInputError(
            f"transfer syntax {transfer_syntax!r} is not a known DICOM transfer syntax; "
            "re-export the series with a standard one"
        ) from exc
    if not compressed:
        return ""
    try:
        decoder = get_decoder(uid)
    except NotImplementedError as exc:
        raise PixelInputError(
            f"transfer syntax {uid.name or uid}: no decoder in pydicom; convert the series "
            "to an uncompressed syntax (e.g. with dcmdjpeg/gdcmconv)"
        ) from exc
    plugins = decoder.available_plugins
    for name in ("pylibjpeg", "pydicom"):
        if name in plugins:
            return name
    raise PixelInputError(
        f"transfer syntax {uid.name or uid}: no pinned decoder plugin is installed "
        "(install the pylibjpeg plugins listed in pyproject.toml)"
    )


def stored_dtype(h: SliceHeader) -> np.dtype:
    """Little-endian container dtype of the stored values."""
    kinds = {8: "1", 16: "2", 32: "4"}
    if h.bits_allocated not in kinds:
        raise PixelInputError(
            f"{h.path}: BitsAllocated {h.bits_allocated} is not supported for CT (8, 16 or 32)"
        )
    return np.dtype(("<i" if h.pixel_representation else "<u") + kinds[h.bits_allocated])


def stored_range(h: SliceHeader) -> tuple[int, int]:
    """The range of stored values that BitsStored and PixelRepresentation allow."""
    bits = h.bits_stored
    if h.pixel_representation:
        return -(2 ** (bits - 1)), 2 ** (bits - 1) - 1
    return 0, 2**bits - 1


def fix_high_bits(arr: np.ndarray, h: SliceHeader) -> None:
    """In place: mask (unsigned) or sign-extend (signed) the bits above BitsStored."""
    width = arr.dtype.itemsize * 8
    if h.bits_stored >= width:
        return
    if h.pixel_representation:
        shift = width - h.bits_stored
        np.left_shift(arr, shift, out=arr)
        np.right_shift(arr, shift, out=arr)
    else:
        np.bitwise_and(arr, (1 << h.bits_stored) - 1, out=arr)


@lru_cache(maxsize=2)
def _dataset(path: Path, transfer_syntax: str) -> Dataset:
    from pydicom import dcmread
    from pydicom.dataset import FileMetaDataset
    from pydicom.uid import UID

    ds = dcmread(path, force=True)
    if getattr(ds, "file_meta", None) is None or "TransferSyntaxUID" not in ds.file_meta:
        meta = FileMetaDataset()
        meta.TransferSyntaxUID = UID(transfer_syntax)
        ds.file_meta = meta
    return ds


def encapsulation_problem(data: bytes, *, rle: bool) -> str | None:
    """What is wrong with encapsulated PixelData items, or None when their lengths add up.

    Checked before any decoder sees the data, because decoders trust the declared lengths: a
    basic offset table declaring 0xFFFFFFF0 bytes made pydicom raise ``struct.error``; a
    fragment declaring more bytes than follow was decoded from whatever was there. For RLE,
    each fragment's 64-byte header (1..15 segments, offsets from 64, increasing, inside the
    fragment) is checked too.

    Parameters
    ----------
    data : the PixelData value (items, the sequence delimiter excluded).
    rle : check RLE segment headers.
    """
    pos, n, index = 0, len(data), 0
    fragments: list[tuple[int, int]] = []
    offsets: tuple[int, ...] = ()
    while pos < n:
        if pos + 8 > n:
            return f"{n - pos} stray bytes after the last item"
        group, elem, length = struct.unpack_from("<HHI", data, pos)
        if (group << 16) | elem != _ITEM:
            return f"item {index} has tag ({group:04X},{elem:04X}), not an item tag"
        start = pos + 8
        if length > n - start:
            return f"item {index} declares {length} bytes but {n - start} follow"
        if index == 0:
            if length % 4:
                return f"the basic offset table declares {length} bytes, not a multiple of 4"
            offsets = struct.unpack_from(f"<{length // 4}I", data, start)
        else:
            fragments.append((start, length))
        pos, index = start + length, index + 1
    if not fragments:
        return "no compressed fragment follows the basic offset table"
    total = sum(8 + length for _, length in fragments)
    if offsets and (
        offsets[0] != 0
        or any(b <= a for a, b in itertools.pairwise(offsets))
        or (offsets[-1] >= total)
    ):
        return "the basic offset table does not point at fragments inside the data"
    if rle:
        for k, (start, length) in enumerate(fragments):
            problem = _rle_header_problem(data[start : start + length])
            if problem:
                return f"RLE fragment {k + 1}: {problem}"
    return None


def _rle_header_problem(fragment: bytes) -> str | None:
    if len(fragment) < 64:
        return f"{len(fragment)} bytes, shorter than the 64-byte RLE header"
    count, *offsets = struct.unpack_from("<16I", fragment)
    if not 1 <= count <= 15:
        return f"the header declares {count} segments (1 to 15 allowed)"
    used = offsets[:count]
    if (
        used[0] != 64
        or any(b <= a for a, b in itertools.pairwise(used))
        or used[-1] >= len(fragment)
    ):
        return (
            f"segment offsets {list(used)} do not run upwards from 64 inside the "
            f"{len(fragment)}-byte fragment"
        )
    return None


def read_stored(h: SliceHeader, out: np.ndarray | None = None) -> np.ndarray:
    """Stored values of one plane, (rows, cols), high bits fixed.

    Parameters
    ----------
    h : SliceHeader
        The plane.
    out : np.ndarray | None
        Optional (rows, cols) C-contiguous array of :func:`stored_dtype` to read into.
    """
    dtype = stored_dtype(h)
    shape = (h.rows, h.cols)
    if out is None:
        out = np.empty(shape, dtype=dtype)
    if h.pixel_offset is not None:
        try:
            with open_regular(h.path, what="DICOM file", error=OSError) as fh:
                fh.seek(h.pixel_offset)
                got = fh.readinto(out.data.cast("B"))
        except OSError as exc:
            raise PixelInputError(f"{h.path}: cannot read pixel data ({exc})") from exc
        if got != out.nbytes:
            raise PixelInputError(
                f"{h.path}: pixel data truncated ({got} of {out.nbytes} bytes); "
                "the file is incomplete, copy it again"
            )
    else:
        try:
            plugin = decoder_plugin_for(h.transfer_syntax)
        except PixelInputError as exc:
            raise PixelInputError(f"{h.path}: {exc}") from exc
        from pydicom.uid import UID, RLELossless

        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                ds = _dataset(h.path, h.transfer_syntax)
                raw = ds.get("PixelData")
                problem = None
                if raw is not None and UID(h.transfer_syntax).is_encapsulated:
                    rle = h.transfer_syntax == RLELossless
                    problem = encapsulation_problem(bytes(raw), rle=rle)
                if problem:
                    raise PixelInputError(
                        f"{h.path}: the compressed pixel data is malformed ({problem}); "
                        "the file is corrupt, copy or export it again"
                    )
                arr, _ = get_decoder(UID(h.transfer_syntax)).as_array(
                    ds, index=h.frame if h.n_frames > 1 else None, decoding_plugin=plugin
                )
        except PixelInputError:
            raise
        except (
            ValueError,
            RuntimeError,
            AttributeError,
            KeyError,
            NotImplementedError,
            EOFError,
            OSError,
            TypeError,
            IndexError,
            MemoryError,
            struct.error,
        ) as exc:
            detail = " ".join(str(exc).split())  # decoders' messages span lines: one line
            raise PixelInputError(
                f"{h.path}: cannot decode pixel data "
                f"({UID(h.transfer_syntax).name or h.transfer_syntax}): {detail}"
            ) from exc
        arr = np.asarray(arr).reshape(shape)
        out[...] = arr.astype(dtype, copy=False)
    fix_high_bits(out, h)
    return out


def padding_mask(stored: np.ndarray, h: SliceHeader) -> np.ndarray | None:
    """(rows, cols) True on padding (PixelPaddingValue, or its range with the range limit)."""
    if h.padding_value is None:
        return None
    lo, hi = stored_range(h)
    pad = h.padding_value
    if h.padding_limit is None:
        if not lo <= pad <= hi:
            # e.g. a signed padding value stored as unsigned: compare the bit pattern.
            pad &= (1 << h.bits_stored) - 1
        return np.asarray(stored == pad)
    a, b = sorted((pad, h.padding_limit))
    return np.asarray((stored >= a) & (stored <= b))


def rescale(h: SliceHeader) -> tuple[float, float]:
    """(slope, intercept), 1 and 0 when absent."""
    slope = 1.0 if h.slope is None else float(h.slope)
    intercept = 0.0 if h.intercept is None else float(h.intercept)
    return slope, intercept


def int16_exact(h: SliceHeader) -> bool:
    """True when every value the stored range allows maps to an integer HU within int16."""
    slope, intercept = rescale(h)
    if slope != round(slope) or intercept != round(intercept):
        return False
    lo, hi = stored_range(h)
    ends = (slope * lo + intercept, slope * hi + intercept)
    return min(ends) >= -32768 and max(ends) <= 32767


def to_hu(stored: np.ndarray, h: SliceHeader, out: np.ndarray) -> bool:
    """Write HU of ``stored`` into ``out`` (int16 or float32); False if int16 cannot hold it."""
    slope, intercept = rescale(h)
    if out.dtype == np.float32:
        out[...] = stored.astype(np.float64) * slope + intercept
        return True
    if int16_exact(h):
        _int16_rescale(stored, slope, intercept, out)
        return True
    if slope != round(slope) or intercept != round(intercept):
        return False
    # Check the actual stored range instead of the one BitsStored allows.
    lo, hi = int(stored.min()), int(stored.max())
    ends = (slope * lo + intercept, slope * hi + intercept)
    if min(ends) < -32768 or max(ends) > 32767:
        return False
    _int16_rescale(stored, slope, intercept, out)
    return True


def _int16_rescale(stored: np.ndarray, slope: float, intercept: float, out: np.ndarray) -> None:
    """``out = stored * slope + intercept`` in integers (both known to be whole and to fit)."""
    if slope == 1.0:
        np.add(stored, np.int32(intercept), out=out, casting="unsafe")
    else:
        np.multiply(stored, np.int32(slope), out=out, casting="unsafe")
        np.add(out, np.int32(intercept), out=out, casting="unsafe")
