"""Find the DICOM image files under a path and read their headers (never the pixels).

A file is DICOM when it has the 128-byte preamble followed by ``DICM``. A file without a
preamble is accepted only when it starts like a DICOM dataset (a group 0x0002 or 0x0008 tag) and
then parses with the tags an image needs; anything else is ignored as not DICOM. Headers are read
with ``stop_before_pixels``; the byte offset of uncompressed pixel data is recorded so that the
pixels can later be read straight into the volume.
"""

from __future__ import annotations

import math
import os
import stat
import struct
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pydicom import dcmread
from pydicom.dataset import Dataset
from pydicom.errors import BytesLengthException, InvalidDicomError
from pydicom.uid import (
    DeflatedExplicitVRLittleEndian,
    ExplicitVRLittleEndian,
    ImplicitVRLittleEndian,
)

from ctdrill.imaging.dicom.fastheader import HeaderCorruptError, read_fast_header
from ctdrill.imaging.errors import ImagingInputError

#: SOP classes that hold CT volumes: CT Image Storage, Enhanced CT, Legacy Converted Enhanced CT.
CT_IMAGE_STORAGE = "1.2.840.10008.5.1.4.1.1.2"
ENHANCED_CT_STORAGE = "1.2.840.10008.5.1.4.1.1.2.1"
LEGACY_ENHANCED_CT_STORAGE = "1.2.840.10008.5.1.4.1.1.2.2"
CT_SOP_CLASSES = (CT_IMAGE_STORAGE, ENHANCED_CT_STORAGE, LEGACY_ENHANCED_CT_STORAGE)
MULTIFRAME_CT_SOP_CLASSES = (ENHANCED_CT_STORAGE, LEGACY_ENHANCED_CT_STORAGE)

#: Transfer syntaxes whose compression loses information.
LOSSY_SYNTAXES = frozenset(
    {
        "1.2.840.10008.1.2.4.50",  # JPEG Baseline
        "1.2.840.10008.1.2.4.51",  # JPEG Extended
        "1.2.840.10008.1.2.4.81",  # JPEG-LS near-lossless
        "1.2.840.10008.1.2.4.91",  # JPEG 2000 (lossy allowed)
        "1.2.840.10008.1.2.4.93",  # JPEG 2000 Part 2 multi-component
        "1.2.840.10008.1.2.4.203",  # HTJ2K (lossy allowed)
    }
)

_FAST_SYNTAXES = (ExplicitVRLittleEndian, ImplicitVRLittleEndian)
#: At most this many bytes are announced to the kernel for read-ahead per scan.
PREFETCH_BYTES = 1 << 30
_PIXEL_TAG = b"\xe0\x7f\x10\x00"
_LONG_VRS = {b"OB", b"OW", b"OF", b"OD", b"OL", b"OV", b"UN", b"SQ", b"UC", b"UR", b"UT", b"SV"}


class DiscoveryInputError(ImagingInputError):
    """The path holds no readable DICOM image."""


@dataclass(frozen=True)
class SliceHeader:
    """One image plane (a single-frame file, or one frame of a multi-frame file).

    Geometry is exactly what the header says: ``ipp`` / ``iop`` in LPS mm,
    ``pixel_spacing`` = (row spacing, column spacing) in mm.
    """

    path: Path
    frame: int
    n_frames: int
    series_uid: str
    sop_class_uid: str
    modality: str
    image_type: tuple[str, ...]
    rows: int
    cols: int
    samples_per_pixel: int
    photometric: str
    bits_allocated: int
    bits_stored: int
    pixel_representation: int
    slope: float | None
    intercept: float | None
    rescale_type: str
    ipp: tuple[float, float, float] | None
    iop: tuple[float, float, float, float, float, float] | None
    pixel_spacing: tuple[float, float] | None
    padding_value: int | None
    padding_limit: int | None
    transfer_syntax: str
    lossy: bool
    #: Byte offset of uncompressed little-endian native pixel data (None: decode with pydicom).
    pixel_offset: int | None
    has_pixels: bool
    #: Declared value length of native PixelData (None when encapsulated), and the file size.
    pixel_length: int | None = None
    file_size: int = 0
    meta: dict[str, Any] = field(default_factory=dict, compare=False, hash=False)

    @property
    def frame_bytes(self) -> int:
        """Bytes of one frame of native pixel data."""
        return self.rows * self.cols * self.samples_per_pixel * (self.bits_allocated // 8)


@dataclass(frozen=True)
class Skipped:
    """A DICOM file that holds no CT image plane, and why."""

    path: Path
    reason: str


@dataclass(frozen=True)
class ScanResult:
    """Everything found under a path."""

    headers: tuple[SliceHeader, ...]
    skipped: tuple[Skipped, ...]
    not_dicom: tuple[Path, ...]


def iter_files(path: Path) -> Iterator[Path]:
    """Every non-directory entry under ``path`` (or ``path`` itself), in a stable order."""
    if path.is_file():
        yield path
        return
    for root, dirs, files in os.walk(path):
        dirs.sort()
        for name in sorted(files):
            yield Path(root) / name


def _is_regular_file(path: Path) -> bool:
    """True when ``path`` (links followed) is a regular file; never opens it."""
    try:
        return stat.S_ISREG(os.stat(path).st_mode)
    except OSError:
        return False


def _looks_like_dicom(path: Path) -> bool | None:
    """True: preamble + DICM; None: maybe a preamble-less dataset; False: not DICOM."""
    try:
        with path.open("rb") as fh:
            head = fh.read(132)
    except OSError:
        return False
    if len(head) == 132 and head[128:132] == b"DICM":
        return True
    if len(head) >= 8 and head[:2] in (b"\x02\x00", b"\x08\x00"):
        return None
    return False


def _num(ds: Any, keyword: str, *, finite_only: bool = True) -> float | None:
    """A numeric tag as float; None when absent or unparsable (or non-finite if asked)."""
    value = ds.get(keyword)
    if value is None or value == "":
        return None
    try:
        number = float(value)
    except (TypeError, ValueError):
        return None
    return number if math.isfinite(number) or not finite_only else None


def _int(ds: Any, keyword: str, default: int | None = None) -> int | None:
    value = ds.get(keyword)
    if value is None or value == "":
        return default
    if isinstance(value, bytes):
        # US-or-SS element read without PixelRepresentation context.
        return int.from_bytes(value[:2], "little", signed=bool(ds.get("PixelRepresentation", 0)))
    try:
        return int(value)
    except (TypeError, ValueError):
        return default


def _floats(value: Any, n: int) -> tuple[float, ...] | None:
    if value is None:
        return None
    try:
        out = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        return None
    return out if len(out) == n else None


def _fg_item(ds: Any, frame: int, seq_keyword: str) -> Dataset | None:
    """The functional-group item ``seq_keyword`` for ``frame`` (per-frame first, then shared)."""
    for fg_keyword, index in (
        ("PerFrameFunctionalGroupsSequence", frame),
        ("SharedFunctionalGroupsSequence", 0),
    ):
        groups = ds.get(fg_keyword)
        if groups is None or len(groups) <= index:
            continue
        seq = groups[index].get(seq_keyword)
        if seq is not None and len(seq) > 0:
            item: Dataset = seq[0]
            return item
    return None


def _pixel_offset(fh: Any, implicit: bool) -> tuple[int | None, int | None, bool]:
    """(offset, declared length) of native pixel data at the file position, and presence."""
    pos = fh.tell()
    head = fh.read(12)
    if len(head) < 8 or head[:4] != _PIXEL_TAG:
        return None, None, False
    if implicit:
        length = struct.unpack("<I", head[4:8])[0]
        start = pos + 8
    elif head[4:6] in _LONG_VRS:
        length = struct.unpack("<I", head[8:12])[0]
        start = pos + 12
    else:
        length = struct.unpack("<H", head[6:8])[0]
        start = pos + 8
    if length == 0xFFFFFFFF:
        return None, None, True  # encapsulated
    return start, length, length > 0


#: Exceptions pydicom raises (often lazily, on first access) for a damaged header.
_HEADER_ERRORS = (
    InvalidDicomError,
    BytesLengthException,
    OSError,
    ValueError,
    EOFError,
    struct.error,
    TypeError,
    KeyError,
    AttributeError,
    IndexError,
    OverflowError,
    NotImplementedError,
    MemoryError,
    RecursionError,
)


def read_headers(
    path: Path, *, ct_only: bool = True, fast: bool = True
) -> list[SliceHeader] | Skipped | None:
    """Header(s) of one file: a list of planes, a :class:`Skipped`, or None when not DICOM.

    ``ct_only=False`` also returns the planes of non-CT images (used to test decoding).
    ``fast=False`` forces pydicom instead of :mod:`ctdrill.imaging.dicom.fastheader` (tests
    compare).
    """
    kind = _looks_like_dicom(path)
    if kind is False:
        return None
    if kind is True and fast:
        try:
            got = read_fast_header(path)
        except HeaderCorruptError as exc:
            return Skipped(path, f"corrupt DICOM header ({exc})")
        if got is not None and str(got.tags.get("SOPClassUID", "")) not in (
            MULTIFRAME_CT_SOP_CLASSES
        ):
            return _classify(
                path,
                got.tags,
                got.transfer_syntax,
                (got.pixel_offset, got.pixel_length, got.has_pixels, got.file_size),
                ct_only,
            )
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with path.open("rb") as fh:
                ds = dcmread(fh, stop_before_pixels=True, force=kind is None)
                implicit, little = ds.original_encoding
                offset, length, has_pixels = _pixel_offset(fh, bool(implicit))
            if kind is None and not ("SOPClassUID" in ds and "Rows" in ds and "Columns" in ds):
                return None
            meta = getattr(ds, "file_meta", None)
            ts = str(meta.get("TransferSyntaxUID", "")) if meta is not None else ""
            if not ts:
                ts = str(ImplicitVRLittleEndian if implicit else ExplicitVRLittleEndian)
            if not little:
                offset = length = None
            if ts == DeflatedExplicitVRLittleEndian:
                # The file position is in the deflated stream: ask the inflated dataset.
                full = dcmread(path)
                offset = length = None
                has_pixels = "PixelData" in full or "FloatPixelData" in full
            size = path.stat().st_size
            return _classify(path, ds, ts, (offset, length, has_pixels, size), ct_only)
    except _HEADER_ERRORS as exc:
        if kind is None:
            return None
        return Skipped(path, f"unreadable DICOM header ({type(exc).__name__})")


def _classify(
    path: Path,
    ds: Any,
    ts: str,
    pixels: tuple[int | None, int | None, bool, int],
    ct_only: bool,
) -> list[SliceHeader] | Skipped:
    offset, length, has_pixels, size = pixels
    sop = str(ds.get("SOPClassUID", ""))
    if sop == "1.2.840.10008.1.3.10" or "DirectoryRecordSequence" in ds:
        return Skipped(path, "directory file (DICOMDIR)")
    if not has_pixels:
        return Skipped(path, "no pixel data")
    if ct_only and sop not in CT_SOP_CLASSES:
        return Skipped(path, f"not a CT image ({_sop_name(sop)})")
    n_frames = _int(ds, "NumberOfFrames", 1) or 1
    if n_frames < 1 or n_frames > max(1, size // 8):
        return Skipped(path, f"NumberOfFrames {n_frames} cannot fit in a {size}-byte file")
    if ts not in _FAST_SYNTAXES:
        offset = length = None
    return _planes(path, ds, sop, ts, offset, length, size)


def _sop_name(sop: str) -> str:
    from pydicom.uid import UID

    name = UID(sop).name if sop else "no SOP class"
    return name or sop


def _planes(
    path: Path,
    ds: Any,
    sop: str,
    ts: str,
    offset: int | None,
    pixel_length: int | None,
    file_size: int,
) -> list[SliceHeader]:
    n_frames = _int(ds, "NumberOfFrames", 1) or 1
    lossy_tag = str(ds.get("LossyImageCompression", "")).strip() == "01"
    meta = {
        "study_description": str(ds.get("StudyDescription", "")),
        "series_description": str(ds.get("SeriesDescription", "")),
        "manufacturer": str(ds.get("Manufacturer", "")),
        "model": str(ds.get("ManufacturerModelName", "")),
        "kvp": _num(ds, "KVP"),
        "kernel": _kernel(ds),
        "slice_thickness_mm": _num(ds, "SliceThickness"),
        "spacing_between_slices_mm": _num(ds, "SpacingBetweenSlices"),
        "gantry_tilt_deg": _num(ds, "GantryDetectorTilt"),
    }
    common: dict[str, Any] = {
        "path": path,
        "n_frames": n_frames,
        "series_uid": str(ds.get("SeriesInstanceUID", "")),
        "sop_class_uid": sop,
        "modality": str(ds.get("Modality", "")),
        "image_type": tuple(str(v).strip().upper() for v in _multi(ds.get("ImageType"))),
        "rows": _int(ds, "Rows", 0),
        "cols": _int(ds, "Columns", 0),
        "samples_per_pixel": _int(ds, "SamplesPerPixel", 1),
        "photometric": str(ds.get("PhotometricInterpretation", "")).strip().upper(),
        "bits_allocated": _int(ds, "BitsAllocated", 0),
        "bits_stored": _int(ds, "BitsStored", _int(ds, "BitsAllocated", 0)),
        "pixel_representation": _int(ds, "PixelRepresentation", 0),
        "padding_value": _int(ds, "PixelPaddingValue"),
        "padding_limit": _int(ds, "PixelPaddingRangeLimit"),
        "transfer_syntax": ts,
        "lossy": lossy_tag or ts in LOSSY_SYNTAXES,
        "has_pixels": True,
        "pixel_length": pixel_length,
        "file_size": file_size,
        "meta": meta,
    }
    if sop not in MULTIFRAME_CT_SOP_CLASSES:
        return [
            SliceHeader(
                frame=0,
                slope=_num(ds, "RescaleSlope", finite_only=False),
                intercept=_num(ds, "RescaleIntercept", finite_only=False),
                rescale_type=str(ds.get("RescaleType", "")).strip(),
                ipp=_floats(ds.get("ImagePositionPatient"), 3),  # type: ignore[arg-type]
                iop=_floats(ds.get("ImageOrientationPatient"), 6),  # type: ignore[arg-type]
                pixel_spacing=_floats(ds.get("PixelSpacing"), 2),  # type: ignore[arg-type]
                pixel_offset=offset,
                **common,
            )
        ]
    planes = []
    frame_bytes = common["rows"] * common["cols"] * common["samples_per_pixel"]
    frame_bytes *= common["bits_allocated"] // 8
    for f in range(n_frames):
        pos = _fg_item(ds, f, "PlanePositionSequence")
        ori = _fg_item(ds, f, "PlaneOrientationSequence")
        meas = _fg_item(ds, f, "PixelMeasuresSequence")
        pvt = _fg_item(ds, f, "PixelValueTransformationSequence")
        ipp = _floats(pos.get("ImagePositionPatient") if pos else ds.get("ImagePositionPatient"), 3)
        iop = _floats(
            ori.get("ImageOrientationPatient") if ori else ds.get("ImageOrientationPatient"), 6
        )
        spacing = _floats(meas.get("PixelSpacing") if meas else ds.get("PixelSpacing"), 2)
        src = pvt if pvt is not None else ds
        frame_meta = dict(meta)
        if meas is not None and _num(meas, "SliceThickness") is not None:
            frame_meta["slice_thickness_mm"] = _num(meas, "SliceThickness")
        planes.append(
            SliceHeader(
                frame=f,
                slope=_num(src, "RescaleSlope", finite_only=False),
                intercept=_num(src, "RescaleIntercept", finite_only=False),
                rescale_type=str(src.get("RescaleType", "")).strip(),
                ipp=ipp,  # type: ignore[arg-type]
                iop=iop,  # type: ignore[arg-type]
                pixel_spacing=spacing,  # type: ignore[arg-type]
                pixel_offset=None if offset is None else offset + f * frame_bytes,
                **{**common, "meta": frame_meta},
            )
        )
    return planes


def _multi(value: Any) -> list[Any]:
    if value is None:
        return []
    if isinstance(value, str | bytes):
        return [value]
    try:
        return list(value)
    except TypeError:
        return [value]


def _kernel(ds: Any) -> str:
    return "\\".join(str(v) for v in _multi(ds.get("ConvolutionKernel")))


def _prefetch(files: list[Path]) -> None:
    """Ask the kernel to start reading every file now, so that cold reads overlap."""
    advise = getattr(os, "posix_fadvise", None)
    if advise is None:
        return
    budget = PREFETCH_BYTES
    for file in files:
        try:
            fd = os.open(file, os.O_RDONLY)
        except OSError:
            continue
        try:
            size = os.fstat(fd).st_size
            if size <= budget:
                advise(fd, 0, size, os.POSIX_FADV_WILLNEED)
                budget -= size
        except OSError:
            pass
        finally:
            os.close(fd)
        if budget <= 0:
            return


def scan(path: str | Path) -> ScanResult:
    """Read the headers of every DICOM file under ``path``.

    Raises
    ------
    DiscoveryInputError
        ``path`` does not exist.
    """
    root = Path(path)
    if not root.exists():
        raise DiscoveryInputError(f"{root}: no such file or folder; give a DICOM series folder")
    headers: list[SliceHeader] = []
    skipped: list[Skipped] = []
    not_dicom: list[Path] = []
    files: list[Path] = []
    for file in iter_files(root):
        if _is_regular_file(file):
            files.append(file)
        else:  # a pipe, device or socket would block or never end: never open it
            skipped.append(Skipped(file, "not a regular file (pipe, device or socket)"))
    _prefetch(files)
    for file in files:
        got = read_headers(file)
        if got is None:
            not_dicom.append(file)
        elif isinstance(got, Skipped):
            skipped.append(got)
        else:
            headers.extend(got)
    return ScanResult(tuple(headers), tuple(skipped), tuple(not_dicom))
