"""DICOM Segmentation (SEG) objects as landmarks, read with pydicom: exact geometry or refused.

ctdrill already depends on pydicom; highdicom (the reference library for SEG) would add about
29 MB installed (highdicom 27 MB, pyjpegls 1.5 MB) and 2.5 s of import (measured here) to the
runtime for one parse that pydicom does directly. The tests write their SEG files with
highdicom, so this reader is checked against an independent implementation.

What is read: a Segmentation Storage object (SOP class 1.2.840.10008.5.1.4.1.1.66.4),
``SegmentationType`` BINARY (FRACTIONAL is refused: ctdrill does not guess a threshold).
Each segment (``SegmentSequence``: ``SegmentNumber``, ``SegmentLabel``) is a landmark; its
frames are those whose ``SegmentIdentificationSequence`` names it. The grid comes from the
functional groups (per-frame, else shared): ``PlaneOrientationSequence``
(``ImageOrientationPatient``: row direction = +i, column direction = +j),
``PixelMeasuresSequence`` (``PixelSpacing`` = row spacing (j), column spacing (i);
``SpacingBetweenSlices`` when given) and each frame's ``PlanePositionSequence``
(``ImagePositionPatient``). DICOM patient coordinates are LPS already.

Every frame's own functional groups are honoured: each frame is placed by its own
``ImagePositionPatient``, and a segment whose frames give different ``PixelSpacing``,
``SpacingBetweenSlices``, ``SliceThickness`` or orientation is refused naming both frames
(one frame's spacing applied to all moved the others: 0.45 against 0.4 mm moved the stop
0.5 mm). The SEG's ``FrameOfReferenceUID`` travels with its landmarks; a CT of another Frame of
Reference is refused naming both (:func:`ctdrill.imaging.sampling.path.require_grid_for_masks`).

Every field is checked before it is used, and a failure names the file, the field and (for
per-frame values) the frame: a missing or empty ``SegmentSequence``, ``SegmentNumber`` or
``ReferencedSegmentNumber``, a ``PixelSpacing`` that is not two positive numbers, orientation
vectors that are not unit and perpendicular (:func:`ctdrill.imaging.volumes.grid.
check_direction_cosines`: a vector scaled x10 is refused, never rescaled), non-finite positions.
Frames are placed on a regular slice grid by their position; frames that do not lie on one
(within :data:`GRID_TOLERANCE_MM`) are refused, and slices with no frame are empty (SEG omits
empty frames). The grid's size is checked against the mask bound before it is allocated (a
10 kB file whose ``SpacingBetweenSlices`` puts 800,000 slices between two frames is refused),
and the result is a proper grid (:func:`ctdrill.imaging.volumes.grid.check_grid`).
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ctdrill.imaging.plan.labels import (
    MAX_MASK_FILE_BYTES,
    MAX_SEGMENTS,
    Labels,
    check_mask_voxels,
)
from ctdrill.imaging.plan.landmark_base import LandmarkInputError
from ctdrill.imaging.volumes.grid import check_direction_cosines, check_grid

SEG_SOP_CLASS = "1.2.840.10008.5.1.4.1.1.66.4"
#: Most frames read from one SEG (117 segments of a 600-slice CT make 70 200).
MAX_SEG_FRAMES = 200_000
#: Positions within this of the slice grid are on it, mm.
GRID_TOLERANCE_MM = 1e-3


def _item(ds: Any, index: int, seq: str) -> Any:
    """The first item of functional group ``seq`` for frame ``index`` (per-frame, else shared)."""
    per_frame = ds.get("PerFrameFunctionalGroupsSequence")
    if per_frame is not None and index < len(per_frame) and seq in per_frame[index]:
        items = per_frame[index][seq].value
        return items[0] if items else None
    shared = ds.get("SharedFunctionalGroupsSequence")
    if shared and seq in shared[0]:
        items = shared[0][seq].value
        return items[0] if items else None
    return None


def _numbers(path: Path, item: Any, name: str, count: int, where: str) -> np.ndarray:
    """``count`` finite numbers of attribute ``name`` of ``item``, or a refusal naming it."""
    raw = None if item is None else item.get(name)
    if raw is None or raw == "":
        raise LandmarkInputError(f"{path}: {where}: {name} is missing")
    values = list(raw) if isinstance(raw, Sequence) and not isinstance(raw, (str, bytes)) else [raw]
    try:
        out = np.array([float(v) for v in values], dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise LandmarkInputError(f"{path}: {where}: {name} {raw!r} is not numbers") from exc
    if out.size != count:
        raise LandmarkInputError(
            f"{path}: {where}: {name} holds {out.size} value(s), a SEG gives {count}"
        )
    if not np.all(np.isfinite(out)):
        raise LandmarkInputError(
            f"{path}: {where}: {name} {out.tolist()} is not finite; the geometry cannot be known"
        )
    return out


def _whole(path: Path, item: Any, name: str, where: str) -> int:
    raw = None if item is None else item.get(name)
    try:
        return int(raw)  # type: ignore[arg-type]
    except (TypeError, ValueError) as exc:
        shown = "missing" if raw is None or raw == "" else repr(raw)
        raise LandmarkInputError(f"{path}: {where}: {name} is {shown}, not a number") from exc


def _dataset(path: Path) -> Any:
    import pydicom
    from pydicom.errors import InvalidDicomError

    from ctdrill.safeio import read_bytes_bounded

    data = read_bytes_bounded(
        path, what="DICOM SEG file", error=LandmarkInputError, max_bytes=MAX_MASK_FILE_BYTES
    )
    try:
        return pydicom.dcmread(io.BytesIO(data))
    except (InvalidDicomError, ValueError, KeyError, EOFError, OSError, TypeError) as exc:
        raise LandmarkInputError(f"{path}: not a readable DICOM file ({exc})") from exc
    except RecursionError as exc:
        raise LandmarkInputError(f"{path}: DICOM sequences nested too deep") from exc


def read_dicom_seg(path: Path) -> Labels:
    """Every segment of a DICOM SEG file."""

    ds = _dataset(path)
    if str(ds.get("SOPClassUID", "")) != SEG_SOP_CLASS:
        raise LandmarkInputError(
            f"{path}: not a DICOM Segmentation (SOP class {ds.get('SOPClassUID', 'missing')}); "
            "masks from DICOM are read from SEG objects"
        )
    if str(ds.get("SegmentationType", "")) != "BINARY":
        raise LandmarkInputError(
            f"{path}: SegmentationType {ds.get('SegmentationType')!r}: only BINARY segments are "
            "read (ctdrill does not choose a threshold for FRACTIONAL ones)"
        )
    rows, cols = _whole(path, ds, "Rows", "the header"), _whole(path, ds, "Columns", "the header")
    n_frames = _whole(path, ds, "NumberOfFrames", "the header") if "NumberOfFrames" in ds else 1
    check_mask_voxels(path, (n_frames, rows, cols), 1, "NumberOfFrames x Rows x Columns")
    per_frame = ds.get("PerFrameFunctionalGroupsSequence")
    if n_frames > MAX_SEG_FRAMES or (per_frame is not None and len(per_frame) != n_frames):
        held = "none" if per_frame is None else len(per_frame)
        raise LandmarkInputError(
            f"{path}: NumberOfFrames {n_frames} (at most {MAX_SEG_FRAMES}) against "
            f"PerFrameFunctionalGroupsSequence items {held}: a SEG gives one item per frame"
        )
    segments = ds.get("SegmentSequence")
    if not segments:
        raise LandmarkInputError(
            f"{path}: SegmentSequence is missing or empty: the SEG names no segment"
        )
    if len(segments) > MAX_SEGMENTS:
        raise LandmarkInputError(
            f"{path}: SegmentSequence holds {len(segments)} segments, more than the "
            f"{MAX_SEGMENTS} read"
        )
    numbers = [
        _whole(path, seg, "SegmentNumber", f"segment item {n + 1}")
        for n, seg in enumerate(segments)
    ]
    if len(set(numbers)) != len(numbers):
        raise LandmarkInputError(f"{path}: SegmentSequence gives one SegmentNumber twice")
    referenced = [
        _whole(
            path,
            _item(ds, f, "SegmentIdentificationSequence"),
            "ReferencedSegmentNumber",
            f"frame {f + 1} (SegmentIdentificationSequence)",
        )
        for f in range(n_frames)
    ]
    unknown = sorted(set(referenced) - set(numbers))
    if unknown:
        raise LandmarkInputError(
            f"{path}: ReferencedSegmentNumber {unknown[0]} names no segment of SegmentSequence"
        )
    try:
        frames = np.asarray(ds.pixel_array).reshape(n_frames, rows, cols)
    except Exception as exc:  # pydicom's decoders raise many types
        raise LandmarkInputError(f"{path}: the SEG pixel data cannot be decoded ({exc})") from exc
    frame_of_reference = str(ds.get("FrameOfReferenceUID", "") or "").strip()
    labels = Labels(path, named=True, frame_of_reference_uid=frame_of_reference or None)
    frames_of: dict[int, list[int]] = {}
    for f, number in enumerate(referenced):
        frames_of.setdefault(number, []).append(f)
    for seg, number in zip(segments, numbers, strict=True):
        name = str(seg.get("SegmentLabel", "") or "").strip() or f"segment {number}"
        idx = frames_of.get(number, [])
        if not idx:
            continue
        mask, affine = _segment_volume(path, ds, frames, idx, name)
        labels.items.append((name, number, mask, affine))
    return labels


def _orientation(path: Path, ds: Any, frame: int) -> np.ndarray:
    where = f"frame {frame + 1} (PlaneOrientationSequence)"
    iop = _numbers(
        path, _item(ds, frame, "PlaneOrientationSequence"), "ImageOrientationPatient", 6, where
    )
    check_direction_cosines(
        iop.reshape(2, 3),
        where=f"{path}",
        field=f"{where} ImageOrientationPatient",
        error=LandmarkInputError,
    )
    return iop


#: Per-frame pixel measures that place voxels: each frame of a segment must give the same.
_MEASURES = (("PixelSpacing", 2), ("SpacingBetweenSlices", 1), ("SliceThickness", 1))
#: Relative tolerance between two frames' measures (DS strings of 16 characters).
_MEASURE_RTOL = 1e-6


def _same_measures(path: Path, ds: Any, idx: list[int], name: str) -> None:
    """Refuse a segment whose frames give different pixel measures (per-frame
    ``PixelMeasuresSequence``): one spacing applied to all would move the others' voxels."""
    first = _item(ds, idx[0], "PixelMeasuresSequence")
    for f in idx[1:]:
        item = _item(ds, f, "PixelMeasuresSequence")
        if item is first:
            continue
        for key, count in _MEASURES:
            a = None if first is None else first.get(key)
            b = None if item is None else item.get(key)
            if (a in (None, "")) and (b in (None, "")):
                continue
            where = f"frame {f + 1} (PixelMeasuresSequence)"
            if a in (None, "") or b in (None, ""):
                differ = True
            else:
                va = _numbers(path, first, key, count, f"frame {idx[0] + 1}")
                vb = _numbers(path, item, key, count, where)
                differ = not np.allclose(va, vb, rtol=_MEASURE_RTOL, atol=0.0)
            if differ:
                raise LandmarkInputError(
                    f"{path}: segment {name!r}: {where} {key} {_shown(b)} differs from frame "
                    f"{idx[0] + 1}'s {_shown(a)}; the frames are not one voxel grid (ctdrill "
                    "does not resample): export the segmentation again on one grid"
                )


def _shown(value: Any) -> str:
    if value in (None, ""):
        return "(missing)"
    if isinstance(value, Sequence) and not isinstance(value, (str, bytes)):
        return "[" + ", ".join(str(v) for v in value) + "]"
    return str(value)


def _segment_volume(
    path: Path, ds: Any, frames: np.ndarray, idx: list[int], name: str
) -> tuple[np.ndarray, np.ndarray]:
    """One segment's frames on a regular slice grid: mask (k, j, i) bool and affine_lps."""

    iop = _orientation(path, ds, idx[0])
    where = f"frame {idx[0] + 1} (PixelMeasuresSequence)"
    measures = _item(ds, idx[0], "PixelMeasuresSequence")
    row_spacing, col_spacing = _numbers(path, measures, "PixelSpacing", 2, where)
    if min(row_spacing, col_spacing) <= 0:
        raise LandmarkInputError(f"{path}: {where}: PixelSpacing must be positive")
    e_i, e_j = iop[:3], iop[3:]
    normal = np.cross(e_i, e_j)
    _same_measures(path, ds, idx, name)
    positions = []
    for f in idx:
        if not np.allclose(_orientation(path, ds, f), iop, atol=1e-6):
            raise LandmarkInputError(
                f"{path}: segment {name!r}: frame {f + 1} (PlaneOrientationSequence) "
                f"ImageOrientationPatient differs from frame {idx[0] + 1}'s; the frames are not "
                "one stack"
            )
        positions.append(
            _numbers(
                path,
                _item(ds, f, "PlanePositionSequence"),
                "ImagePositionPatient",
                3,
                f"frame {f + 1} (PlanePositionSequence)",
            )
        )
    ipp = np.asarray(positions, dtype=np.float64)
    along = ipp @ normal
    order = np.argsort(along, kind="stable")
    along, ipp = along[order], ipp[order]
    frame_ids = [idx[o] for o in order]
    gaps = np.diff(along)
    if np.any(gaps < GRID_TOLERANCE_MM):
        raise LandmarkInputError(f"{path}: segment {name!r} has two frames at one position")
    given = measures.get("SpacingBetweenSlices") if measures is not None else None
    if given not in (None, ""):
        step_mm = float(_numbers(path, measures, "SpacingBetweenSlices", 1, where)[0])
    elif len(gaps):
        step_mm = float(gaps.min())
    else:
        step_mm = float(measures.get("SliceThickness", 1.0) or 1.0)
    if not (np.isfinite(step_mm) and step_mm > 0):
        raise LandmarkInputError(f"{path}: segment {name!r}: slice spacing is not positive")
    span = float(along[-1] - along[0])
    n_slices = round(span / step_mm) + 1 if span / step_mm < 1e15 else 10**15
    check_mask_voxels(
        path,
        (n_slices, frames.shape[1], frames.shape[2]),
        1,
        f"segment {name!r}: frames {span:.6g} mm apart at SpacingBetweenSlices {step_mm:g} mm "
        f"({n_slices} slices)",
    )
    k = np.rint((along - along[0]) / step_mm).astype(np.int64)
    if np.any(np.abs(along - along[0] - k * step_mm) > GRID_TOLERANCE_MM):
        raise LandmarkInputError(
            f"{path}: segment {name!r}: frames are not on a regular slice grid "
            f"({step_mm:g} mm); resample the segmentation"
        )
    step = (ipp[-1] - ipp[0]) / k[-1] if k[-1] > 0 else normal * step_mm
    if np.any(np.abs(ipp - (ipp[0] + k[:, None] * step)) > GRID_TOLERANCE_MM):
        raise LandmarkInputError(
            f"{path}: segment {name!r}: frame positions are not on one line of slices"
        )
    affine = np.eye(4)
    affine[:3, 0] = e_i * col_spacing
    affine[:3, 1] = e_j * row_spacing
    affine[:3, 2] = step
    affine[:3, 3] = ipp[0]
    shape = (int(k[-1]) + 1, frames.shape[1], frames.shape[2])
    check_grid(
        affine,
        shape,
        where=str(path),
        field=f"segment {name!r} (PixelSpacing, ImageOrientationPatient, ImagePositionPatient)",
        error=LandmarkInputError,
    )
    mask = np.zeros(shape, dtype=bool)
    for kk, f in zip(k, frame_ids, strict=True):
        mask[kk] = frames[f] != 0
    return mask, affine
