"""Segmentations and labelmaps as landmarks, each on its own grid, in LPS.

A mask landmark (``{"kind": "mask", "path": ..., "segment": NAME}`` or ``"label": N`` in a
plan, or the file itself given as a plan input) is read from (the format by the file's content,
:func:`mask_format`, not its name):

- ``.npy``: a labelmap on the CT grid (or on ``affine_lps`` given in the plan). It carries no
  geometry and no axis order: the plan's ``axes`` says ``kji`` (slices, rows, cols) or
  ``ijk`` (cols, rows, slices, nibabel's order); without it the mask is refused where another
  axis order would fit the CT grid too (a CT with as many columns as slices); the header's
  shape x item size is checked against :data:`MAX_MASK_BYTES` before
  anything is allocated, and a ``.npz`` (zip) or any non-NPY file is refused.
- a 3D Slicer segmentation (``.seg.nrrd``: a NRRD with ``SegmentN_`` fields): every segment is a
  landmark named by its ``SegmentN_Name``; its voxels are those of its layer equal to its
  ``SegmentN_LabelValue``.
- a labelmap in NRRD (``.nrrd``, ``.nhdr``), NIfTI (``.nii``, ``.nii.gz``) or MetaImage
  (``.mha``, ``.mhd``): one landmark per label value.
- a DICOM Segmentation (SEG) object, read with pydicom (:mod:`.dicomseg`).

The volume formats are read by :mod:`ctdrill.imaging.volumes`, the CT's own readers: geometry
exact or refused under one set of rules (:mod:`ctdrill.imaging.volumes.grid`), sizes checked
before anything is allocated or inflated, and a NIfTI whose qform and sform disagree refused (a
canal must not move with a reader's choice). Each gives ``MaskLandmark(name, mask,
affine_lps)`` with ``mask`` (k, j, i) and ``affine_lps`` mapping ``(i, j, k, 1)`` to LPS mm, so
the mask need not lie on the CT grid. At most :data:`MAX_SEGMENTS` segments or label values are
read from one file, and the masks of a file given whole as a plan input hold at most
:data:`MAX_MASK_BYTES` together.
"""

from __future__ import annotations

import os
import re
from dataclasses import replace
from pathlib import Path

import numpy as np

from ctdrill.imaging.plan.labels import (
    MAX_MASK_BYTES,
    MAX_SEGMENTS,
    Labels,
    bounded_file_size,
    check_mask_voxels,
    mask_of,
)
from ctdrill.imaging.plan.landmarks import LandmarkInputError, MaskLandmark
from ctdrill.imaging.plan.mask import AXES_IJK, AXES_KJI
from ctdrill.imaging.plan.read import PlanParts
from ctdrill.imaging.volumes.sniff import read_volume_file, volume_format
from ctdrill.imaging.volumes.types import VolumeData
from ctdrill.safeio import open_regular
from ctdrill.warning_codes import LoadWarning

_SEGMENT_KEY = re.compile(r"Segment\d+_ID")
_SUFFIXES = (".seg.nrrd", ".nii.gz", ".nrrd", ".nhdr", ".nii", ".mha", ".mhd", ".npy", ".dcm")


def _suffix(path: Path) -> str:
    name = path.name.lower()
    for suffix in _SUFFIXES:
        if name.endswith(suffix):
            return suffix
    return path.suffix.lower()


def _integer_labels(path: Path, arr: np.ndarray) -> np.ndarray:
    if arr.dtype == np.bool_ or np.issubdtype(arr.dtype, np.integer):
        return arr
    if (
        np.issubdtype(arr.dtype, np.floating)
        and np.all(np.isfinite(arr))
        and np.array_equal(arr, np.round(arr))
    ):
        return arr
    raise LandmarkInputError(
        f"{path}: a labelmap holds whole numbers, got {arr.dtype} values that are not; "
        "export the segmentation as a labelmap"
    )


# --------------------------------------------------------------------------- .npy


def read_npy(path: Path) -> np.ndarray:
    """A ``.npy`` labelmap, its header checked before the data is allocated."""
    size = bounded_file_size(path)
    fmt = np.lib.format
    try:
        with open_regular(path, what="mask file", error=LandmarkInputError) as fh:
            version = fmt.read_magic(fh)
            if version == (1, 0):
                shape, fortran, dtype = fmt.read_array_header_1_0(fh)
            elif version in ((2, 0), (3, 0)):
                shape, fortran, dtype = fmt.read_array_header_2_0(fh)
            else:
                raise ValueError(f"unsupported .npy version {version}")
            if dtype.hasobject:
                raise ValueError("object arrays are not labelmaps")
            if any(int(n) < 0 for n in shape):
                raise ValueError(f"the header declares a negative size {shape}")
            if 0 not in shape:
                check_mask_voxels(path, tuple(shape), dtype.itemsize, "the header")
            data_bytes = int(np.prod(shape, dtype=np.int64)) * dtype.itemsize
            if data_bytes > size - fh.tell():
                raise ValueError(
                    f"the header declares {data_bytes} bytes of data, the file holds "
                    f"{size - fh.tell()}"
                )
            fh.seek(0)
            arr = fmt.read_array(fh, allow_pickle=False)
    except LandmarkInputError:
        raise
    except (OSError, ValueError, EOFError) as exc:
        raise LandmarkInputError(
            f"{path}: not a readable .npy labelmap ({exc}); save the mask with numpy.save "
            "(not savez)"
        ) from exc
    if fortran:
        arr = np.ascontiguousarray(arr)
    return arr


def load_mask_file(path: Path, *, label: int | None = None) -> np.ndarray:
    """Read a labelmap ``.npy`` (slices, rows, cols) as a bool mask.

    ``label`` selects one label value; ``None`` takes every non-zero voxel. The file is
    checked (regular, bounded, an NPY header whose size fits) before the array is allocated
    (:func:`read_npy`); other formats are read by :func:`mask_landmark`.
    """
    if path.suffix.lower() != ".npy":
        raise LandmarkInputError(
            f"{path}: mask landmarks are read from NumPy .npy labelmaps on the CT grid "
            "(slices, rows, cols); convert the segmentation to .npy"
        )
    arr = read_npy(path)
    if arr.ndim != 3:
        raise LandmarkInputError(
            f"{path}: expected a 3-D labelmap (slices, rows, cols), got shape {arr.shape}"
        )
    if not (np.issubdtype(arr.dtype, np.integer) or arr.dtype == np.bool_):
        raise LandmarkInputError(f"{path}: labelmap must be integer or bool, got {arr.dtype}")
    mask: np.ndarray = arr != 0 if label is None else arr == label
    if not mask.any():
        raise LandmarkInputError(
            f"{path}: the mask is empty" + ("" if label is None else f" for label {label}")
        )
    return mask


# --------------------------------------------------------------------------- volume files


def mask_format(path: Path) -> str:
    """``npy``, ``dicom``, ``nifti``, ``nrrd`` or ``metaimage``: the mask file's format by its
    content (:func:`ctdrill.imaging.volumes.sniff.volume_format`)."""
    bounded_file_size(path)
    if _suffix(path) == ".npy":
        return "npy"
    try:
        with open_regular(path, what="mask file", error=LandmarkInputError) as fh:
            if fh.read(6) == b"\x93NUMPY":
                return "npy"
    except OSError as exc:
        raise LandmarkInputError(f"{path}: cannot read the mask file ({exc})") from exc
    return volume_format(path, error=LandmarkInputError, what="mask file")


def _segment_count(path: Path, fields: dict[str, str]) -> int:
    """How many ``SegmentN_`` entries a NRRD header holds (0: a plain labelmap)."""
    ids = [k for k in fields if _SEGMENT_KEY.fullmatch(k)]
    if len(ids) > MAX_SEGMENTS:
        raise LandmarkInputError(
            f"{path}: the header declares {len(ids)} segments, more than the {MAX_SEGMENTS} "
            "read; export the segments you mean to protect"
        )
    n = 0
    while n <= MAX_SEGMENTS and (f"Segment{n}_ID" in fields or f"Segment{n}_Name" in fields):
        n += 1
    return n


def _slicer_labels(path: Path, vol: VolumeData, n_segments: int) -> Labels:
    """A 3D Slicer segmentation: one entry per segment, named by its ``SegmentN_Name``."""
    layers = vol.data if vol.data.ndim == 4 else vol.data[None]
    labels = Labels(path, named=True)
    fields = vol.fields
    for n in range(n_segments):
        name = fields.get(f"Segment{n}_Name", "").strip() or f"segment {n}"
        try:
            value = int(fields.get(f"Segment{n}_LabelValue", "1"))
            layer = int(fields.get(f"Segment{n}_Layer", "0"))
        except ValueError as exc:
            raise LandmarkInputError(f"{path}: Segment{n} has a malformed label or layer") from exc
        if not 0 <= layer < len(layers):
            raise LandmarkInputError(f"{path}: Segment{n}_Layer {layer} is not a layer")
        labels.items.append((name, value, layers[layer], vol.affine_lps))
    return labels


def _labelmap(path: Path, vol: VolumeData) -> Labels:
    """A labelmap: one entry per label value present."""
    if vol.data.ndim != 3:
        raise LandmarkInputError(
            f"{path}: expected a 3-D labelmap, got {vol.data.ndim} axes (several layers are "
            "read from a 3D Slicer segmentation, with its SegmentN fields)"
        )
    data = vol.data
    if vol.scale is not None:
        data = data * vol.scale[0] + vol.scale[1]
    arr = _integer_labels(path, data)
    values = _values(arr)
    if len(values) > MAX_SEGMENTS:
        raise LandmarkInputError(
            f"{path}: {len(values)} label values, more than the {MAX_SEGMENTS} read; is this a "
            "labelmap? (a CT or a probability map is not)"
        )
    labels = Labels(path)
    for value in values:
        labels.items.append((f"{_stem(path)} label {value}", value, arr, vol.affine_lps))
    return labels


def _stem(path: Path) -> str:
    name = path.name
    suffix = _suffix(path)
    return name[: -len(suffix)] if name.lower().endswith(suffix) else path.stem


def _values(arr: np.ndarray) -> list[int]:
    return [int(v) for v in np.unique(arr) if v != 0]


def read_labels(path: Path) -> Labels:
    """Every labelled mask of a segmentation or labelmap file (not ``.npy``), by content."""
    kind = mask_format(path)
    if kind == "npy":
        raise LandmarkInputError(
            f"{path}: a .npy labelmap has no geometry of its own; name it in a plan as a mask "
            "landmark (kind mask, path, label) on the CT grid"
        )
    if kind == "dicom":
        from ctdrill.imaging.plan.dicomseg import read_dicom_seg

        return read_dicom_seg(path)
    vol = read_volume_file(
        path,
        max_bytes=MAX_MASK_BYTES,
        error=LandmarkInputError,
        refuse_ambiguous=True,
        layers=True,
        kind=kind,
    )
    n_segments = _segment_count(path, vol.fields) if vol.format == "NRRD" else 0
    if n_segments:
        return _slicer_labels(path, vol, n_segments)
    return _labelmap(path, vol)


def mask_landmark(
    path: Path,
    *,
    name: str,
    label: int | None,
    segment: str | None,
    affine_lps: np.ndarray | None,
    margin_mm: float | None,
    source: str,
    axes: str | None = None,
) -> MaskLandmark:
    """The mask landmark a plan names: ``label`` and/or ``segment`` choose what is taken.

    ``axes`` (a ``.npy`` only): the order its axes are stored in, ``kji`` (slices, rows,
    cols) or ``ijk`` (cols, rows, slices, transposed here); None: not stated, and the mask is
    refused where another order would fit the CT grid too (:meth:`MaskLandmark.on_grid`).
    """
    if mask_format(path) == "npy":  # a missing file, FIFO or device is named first
        if segment is not None:
            raise LandmarkInputError(f"{path}: a .npy labelmap has no named segments; use label")
        mask = load_mask_file(path, label=label)
        if axes == AXES_IJK:
            mask = np.ascontiguousarray(mask.transpose(2, 1, 0))
        lm = _nonempty(path, name, mask, affine_lps, margin_mm, source, label, None)
        stated = axes if axes is not None else (AXES_KJI if affine_lps is not None else None)
        return replace(lm, axes=stated)
    if axes is not None:
        raise LandmarkInputError(
            f"{path}: this file carries its own geometry and axis order; remove axes from the "
            "landmark (it is for .npy labelmaps)"
        )
    if affine_lps is not None:
        raise LandmarkInputError(
            f"{path}: this file carries its own geometry; remove affine_lps from the landmark"
        )
    labels = read_labels(path)
    chosen = [
        it
        for it in labels.items
        if (segment is None or it[0] == segment) and (label is None or it[1] == label)
    ]
    if segment is not None and not chosen:
        names = ", ".join(repr(it[0]) for it in labels.items)
        raise LandmarkInputError(f"{path}: no segment named {segment!r} (segments: {names})")
    if not chosen:
        raise LandmarkInputError(
            f"{path}: the mask is empty" + ("" if label is None else f" for label {label}")
        )
    first = chosen[0]
    mask = np.zeros(first[2].shape, dtype=bool)
    for _, value, arr, _ in chosen:
        mask |= mask_of(arr, value)
    lm = _nonempty(path, name, mask, first[3], margin_mm, source, label, segment)
    return replace(lm, frame_of_reference_uid=labels.frame_of_reference_uid)


def _nonempty(
    path: Path,
    name: str,
    mask: np.ndarray,
    affine: np.ndarray | None,
    margin_mm: float | None,
    source: str,
    label: int | None,
    segment: str | None,
) -> MaskLandmark:
    if not mask.any():
        what = "" if label is None else f" for label {label}"
        what += "" if segment is None else f" in segment {segment!r}"
        raise LandmarkInputError(f"{path}: the mask is empty{what}")
    return MaskLandmark(
        name,
        mask,
        affine_lps=affine,
        margin_mm=margin_mm,
        source=source,
        label=label,
        segment=segment,
    )


def segmentation_parts(path: Path) -> PlanParts:
    """A segmentation or labelmap given as a plan input: every segment/label a landmark."""
    labels = read_labels(path)
    need = sum(int(arr.size) for _, _, arr, _ in labels.items)
    if need > MAX_MASK_BYTES:
        raise LandmarkInputError(
            f"{path}: its {len(labels.items)} segments would need {need} bytes of masks, more "
            f"than the {MAX_MASK_BYTES} accepted; name the ones to protect in a plan (kind "
            "mask, path, segment or label)"
        )
    source = os.fspath(path.resolve())
    out = []
    empty = []
    for name, value, arr, affine in labels.items:
        mask = mask_of(arr, value)
        if not mask.any():
            empty.append(name)  # Slicer keeps a segment with no voxel: nothing to protect
            continue
        out.append(
            MaskLandmark(
                name,
                mask,
                affine_lps=affine,
                source=source,
                label=None if labels.named else value,
                segment=name if labels.named else None,
                frame_of_reference_uid=labels.frame_of_reference_uid,
            )
        )
    if not out:
        raise LandmarkInputError(f"{path}: the segmentation holds no labelled voxel")
    warnings: tuple[LoadWarning, ...] = ()
    if empty:
        names = ", ".join(repr(n) for n in empty)
        warnings = (
            LoadWarning("segment_empty", f"{path.name}: segments with no voxel skipped: {names}"),
        )
    return PlanParts(path, (), tuple(out), (), warnings)
