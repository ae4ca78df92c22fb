"""A DICOM header dataset -> the image planes it holds (:class:`SliceHeader`), or why none.

Single-frame CT gives one plane; Enhanced and Legacy Converted Enhanced CT give one per frame,
their geometry and rescale taken from the per-frame functional groups first, then the shared
ones. Works on a pydicom ``Dataset`` and on the fast reader's tag dictionary alike.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ctdrill.imaging.dicom.slice_header import (
    CT_SOP_CLASSES,
    LOSSY_SYNTAXES,
    MULTIFRAME_CT_SOP_CLASSES,
    NATIVE_SYNTAXES,
    Skipped,
    SliceHeader,
)

if TYPE_CHECKING:  # pydicom is imported only where a file needs it (0.2 s of a start-up)
    from pydicom.dataset import Dataset


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


def classify(
    path: Path,
    ds: Any,
    ts: str,
    pixels: tuple[int | None, int | None, bool, int],
    ct_only: bool,
) -> list[SliceHeader] | Skipped:
    """The planes of one file's header ``ds``, or why it holds none.

    Parameters
    ----------
    path : Path
        The file (recorded in each plane).
    ds : pydicom Dataset or the fast reader's tag dictionary
        The header, read without pixels.
    ts : str
        Transfer syntax UID.
    pixels : tuple
        ``(offset, declared length, has pixel data, file size)`` of native pixel data
        (offset and length None when encapsulated or not little endian).
    ct_only : bool
        Skip images that are not CT.

    Returns
    -------
    list of SliceHeader or Skipped
    """
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
    if ts not in NATIVE_SYNTAXES:
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
        "frame_of_reference_uid": str(ds.get("FrameOfReferenceUID", "") or "").strip(),
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
