"""DICOM Segmentation (SEG) objects as landmarks, read with pydicom.

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
(``ImagePositionPatient``). Frames are placed on a regular slice grid by their position;
frames that do not lie on one (within 1e-3 mm) are refused, and slices with no frame are
empty (SEG omits empty frames). DICOM patient coordinates are LPS already.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ctdrill.imaging.plan.landmarks import LandmarkInputError

SEG_SOP_CLASS = "1.2.840.10008.5.1.4.1.1.66.4"
#: Positions within this of the slice grid are on it, mm.
GRID_TOLERANCE_MM = 1e-3


def _item(ds: Any, index: int, seq: str) -> Any:
    """The first item of functional group ``seq`` for frame ``index`` (per-frame, else shared)."""
    per_frame = getattr(ds, "PerFrameFunctionalGroupsSequence", None)
    if per_frame is not None and index < len(per_frame) and seq in per_frame[index]:
        return per_frame[index][seq][0]
    shared = getattr(ds, "SharedFunctionalGroupsSequence", None)
    if shared and seq in shared[0]:
        return shared[0][seq][0]
    return None


def read_dicom_seg(path: Path) -> Any:
    """Every segment of a DICOM SEG file (``Labels`` of :mod:`.segmentation`)."""
    import pydicom
    from pydicom.errors import InvalidDicomError

    from ctdrill.imaging.plan.segmentation import (
        MAX_MASK_FILE_BYTES,
        Labels,
        _check_voxels,
    )
    from ctdrill.safeio import read_bytes_bounded

    data = read_bytes_bounded(
        path, what="DICOM SEG file", error=LandmarkInputError, max_bytes=MAX_MASK_FILE_BYTES
    )
    import io

    try:
        ds = pydicom.dcmread(io.BytesIO(data))
    except (InvalidDicomError, ValueError, KeyError, EOFError, OSError) as exc:
        raise LandmarkInputError(f"{path}: not a readable DICOM file ({exc})") from exc
    except RecursionError as exc:
        raise LandmarkInputError(f"{path}: DICOM sequences nested too deep") from exc
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
    rows, cols = int(ds.Rows), int(ds.Columns)
    n_frames = int(ds.get("NumberOfFrames", 1))
    _check_voxels(path, (n_frames, rows, cols), 1)
    try:
        frames = np.asarray(ds.pixel_array).reshape(n_frames, rows, cols)
    except Exception as exc:  # pydicom's decoders raise many types
        raise LandmarkInputError(f"{path}: the SEG pixel data cannot be decoded ({exc})") from exc
    labels = Labels(path)
    for seg in ds.SegmentSequence:
        number = int(seg.SegmentNumber)
        name = str(seg.get("SegmentLabel", "")).strip() or f"segment {number}"
        idx = [
            f
            for f in range(n_frames)
            if (sid := _item(ds, f, "SegmentIdentificationSequence")) is not None
            and int(sid.ReferencedSegmentNumber) == number
        ]
        if not idx:
            continue
        mask, affine = _segment_volume(path, ds, frames, idx, name)
        labels.items.append((name, number, mask, affine))
    return labels


def _segment_volume(
    path: Path, ds: Any, frames: np.ndarray, idx: list[int], name: str
) -> tuple[np.ndarray, np.ndarray]:
    """One segment's frames on a regular slice grid: mask (k, j, i) bool and affine_lps."""
    orient = _item(ds, idx[0], "PlaneOrientationSequence")
    measures = _item(ds, idx[0], "PixelMeasuresSequence")
    if orient is None or measures is None:
        raise LandmarkInputError(f"{path}: segment {name!r} has no plane orientation or spacing")
    iop = np.asarray([float(v) for v in orient.ImageOrientationPatient], dtype=np.float64)
    row_spacing, col_spacing = (float(v) for v in measures.PixelSpacing)
    e_i, e_j = iop[:3], iop[3:]
    normal = np.cross(e_i, e_j)
    positions = []
    for f in idx:
        o = _item(ds, f, "PlaneOrientationSequence")
        if o is not None and not np.allclose(
            [float(v) for v in o.ImageOrientationPatient], iop, atol=1e-6
        ):
            raise LandmarkInputError(f"{path}: segment {name!r} frames differ in orientation")
        pos = _item(ds, f, "PlanePositionSequence")
        if pos is None:
            raise LandmarkInputError(f"{path}: frame {f + 1} has no ImagePositionPatient")
        positions.append([float(v) for v in pos.ImagePositionPatient])
    ipp = np.asarray(positions, dtype=np.float64)
    along = ipp @ normal
    order = np.argsort(along, kind="stable")
    along, ipp = along[order], ipp[order]
    frame_ids = [idx[o] for o in order]
    gaps = np.diff(along)
    if np.any(gaps < GRID_TOLERANCE_MM):
        raise LandmarkInputError(f"{path}: segment {name!r} has two frames at one position")
    given = measures.get("SpacingBetweenSlices")
    if given is not None:
        step_mm = float(given)
    elif len(gaps):
        step_mm = float(gaps.min())
    else:
        step_mm = float(measures.get("SliceThickness", 1.0) or 1.0)
    if not (np.isfinite(step_mm) and step_mm > 0):
        raise LandmarkInputError(f"{path}: segment {name!r}: slice spacing is not positive")
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
    mask = np.zeros((int(k[-1]) + 1, frames.shape[1], frames.shape[2]), dtype=bool)
    for kk, f in zip(k, frame_ids, strict=True):
        mask[kk] = frames[f] != 0
    affine = np.eye(4)
    affine[:3, 0] = e_i * col_spacing
    affine[:3, 1] = e_j * row_spacing
    affine[:3, 2] = step
    affine[:3, 3] = ipp[0]
    return mask, affine
