"""Segmentations and labelmaps as landmarks, each on its own grid, in LPS.

A mask landmark (``{"kind": "mask", "path": ..., "segment": NAME}`` or ``"label": N`` in a
plan, or the file itself given as a plan input) is read from:

- ``.npy``: a labelmap (slices, rows, cols) on the CT grid (or on ``affine_lps`` given in the
  plan); the header's shape x item size is checked against :data:`MAX_MASK_BYTES` before
  anything is allocated, and a ``.npz`` (zip) or any non-NPY file is refused.
- ``.seg.nrrd``: a 3D Slicer segmentation (pynrrd). Every segment is a landmark named by its
  ``SegmentN_Name``; its voxels are those of its layer equal to its ``SegmentN_LabelValue``.
- ``.nrrd``: a labelmap (pynrrd); ``space`` may be LPS or RAS (converted).
- ``.nii`` / ``.nii.gz``: a labelmap (nibabel). NIfTI coordinates are RAS: the affine
  (nibabel's ``img.affine``: the sform when set, else the qform) is converted to LPS.
- ``.dcm``: a DICOM Segmentation (SEG) object, read with pydicom (see :mod:`.dicomseg`).

Each gives ``MaskLandmark(name, mask, affine_lps)`` with ``mask`` (k, j, i) and ``affine_lps``
mapping ``(i, j, k, 1)`` to LPS mm, so the mask need not lie on the CT grid. Every file is
checked to be a regular file of bounded size before it is opened (:mod:`ctdrill.safeio`).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from ctdrill.imaging.plan.landmarks import LandmarkInputError, MaskLandmark, load_mask_file
from ctdrill.imaging.plan.read import PlanParts
from ctdrill.safeio import regular_file_size

#: Largest mask accepted, bytes of voxel data as declared by the file's header.
MAX_MASK_BYTES = 1 << 30
#: Largest segmentation file read, bytes.
MAX_MASK_FILE_BYTES = 1 << 30
#: LPS from RAS (and back): x and y negated.
RAS_TO_LPS = np.diag([-1.0, -1.0, 1.0, 1.0])


def _suffix(path: Path) -> str:
    name = path.name.lower()
    for suffix in (".seg.nrrd", ".nii.gz", ".nrrd", ".nii", ".npy", ".dcm"):
        if name.endswith(suffix):
            return suffix
    return path.suffix.lower()


class Labels:
    """The labelled masks of one file: ``(name, label value or None, mask, affine_lps)``."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.items: list[tuple[str, int | None, np.ndarray, np.ndarray | None]] = []


def _bounded(path: Path) -> int:
    size = regular_file_size(path, what="mask file", error=LandmarkInputError)
    if size > MAX_MASK_FILE_BYTES:
        raise LandmarkInputError(
            f"{path}: the mask file holds {size} bytes, more than the {MAX_MASK_FILE_BYTES} "
            "accepted; check that this is the right file"
        )
    return size


def _check_voxels(path: Path, shape: tuple[int, ...], itemsize: int) -> None:
    """Refuse a declared size beyond :data:`MAX_MASK_BYTES` before allocating it."""
    if any(int(n) < 0 for n in shape):
        raise LandmarkInputError(f"{path}: the header declares a negative size {shape}")
    total = int(np.prod([int(n) for n in shape], dtype=object)) * int(itemsize)
    if total > MAX_MASK_BYTES:
        raise LandmarkInputError(
            f"{path}: the header declares {shape} voxels of {itemsize} bytes ({total} bytes), "
            f"more than the {MAX_MASK_BYTES} accepted; crop or resample the segmentation"
        )


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
    size = _bounded(path)
    fmt = np.lib.format
    try:
        with open(path, "rb") as fh:
            version = fmt.read_magic(fh)
            if version == (1, 0):
                shape, fortran, dtype = fmt.read_array_header_1_0(fh)
            elif version in ((2, 0), (3, 0)):
                shape, fortran, dtype = fmt.read_array_header_2_0(fh)
            else:
                raise ValueError(f"unsupported .npy version {version}")
            if dtype.hasobject:
                raise ValueError("object arrays are not labelmaps")
            _check_voxels(path, tuple(shape), dtype.itemsize)
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


# --------------------------------------------------------------------------- NRRD


def _nrrd(path: Path) -> tuple[np.ndarray, dict[str, Any]]:
    """NRRD data in C order (slowest axis first) and its header, bounded before reading."""
    import nrrd

    _bounded(path)
    try:
        with open(path, "rb") as fh:
            header = nrrd.read_header(fh)
            if "data file" in header or "datafile" in header:
                raise LandmarkInputError(
                    f"{path}: a detached NRRD (data file field) is not read; save the "
                    "segmentation as a single .nrrd / .seg.nrrd file"
                )
            sizes = tuple(int(n) for n in np.atleast_1d(header.get("sizes", [])))
            dtype = np.dtype(nrrd.reader._determine_datatype(header))
            _check_voxels(path, sizes, dtype.itemsize)
            data = nrrd.read_data(header, fh, str(path), index_order="C")
    except LandmarkInputError:
        raise
    except (nrrd.NRRDError, OSError, ValueError, KeyError, EOFError) as exc:
        raise LandmarkInputError(f"{path}: not a readable NRRD file ({exc})") from exc
    return np.asarray(data), header


def _nrrd_affine(path: Path, header: dict[str, Any], n_spatial: int) -> np.ndarray:
    """LPS affine of the last three (spatial) axes of a NRRD header."""
    space = str(header.get("space", "")).lower()
    if space in ("left-posterior-superior", "lps"):
        flip = np.eye(4)
    elif space in ("right-anterior-superior", "ras"):
        flip = RAS_TO_LPS
    else:
        raise LandmarkInputError(
            f"{path}: NRRD space {header.get('space')!r} is not LPS or RAS; ctdrill needs the "
            "segmentation in patient coordinates"
        )
    dirs = np.asarray(header.get("space directions"), dtype=np.float64)
    origin = np.asarray(header.get("space origin", [np.nan] * 3), dtype=np.float64)
    if dirs.ndim != 2 or dirs.shape[1] != 3 or n_spatial != 3:
        raise LandmarkInputError(f"{path}: expected 3 spatial axes with space directions")
    spatial = dirs[-3:]
    if not (np.all(np.isfinite(spatial)) and np.all(np.isfinite(origin))):
        raise LandmarkInputError(f"{path}: space directions or origin missing or not finite")
    affine = np.eye(4)
    affine[:3, :3] = spatial.T  # columns: the i, j, k steps (file axis order, fastest first)
    affine[:3, 3] = origin
    out: np.ndarray = flip @ affine
    return out


def read_labelmap_nrrd(path: Path) -> Labels:
    """A ``.nrrd`` labelmap: one entry per label value present."""
    data, header = _nrrd(path)
    if data.ndim != 3:
        raise LandmarkInputError(
            f"{path}: expected a 3-D labelmap, got {data.ndim} axes (a .seg.nrrd with "
            "several layers must be named .seg.nrrd)"
        )
    labels = Labels(path)
    arr = _integer_labels(path, data)
    affine = _nrrd_affine(path, header, 3)
    for value in _values(arr):
        labels.items.append((f"{_stem(path)} label {value}", value, arr, affine))
    return labels


def read_seg_nrrd(path: Path) -> Labels:
    """A 3D Slicer ``.seg.nrrd``: one entry per segment, named by its ``SegmentN_Name``."""
    data, header = _nrrd(path)
    if data.ndim == 3:
        layers = data[None]
    elif data.ndim == 4:
        # Slicer writes the layers as the first (fastest) file axis, kind "list": in C order
        # it is the last axis, (k, j, i, layer).
        layers = np.moveaxis(data, -1, 0)
    else:
        raise LandmarkInputError(f"{path}: expected 3 or 4 axes, got {data.ndim}")
    affine = _nrrd_affine(path, header, 3)
    labels = Labels(path)
    n = 0
    while f"Segment{n}_ID" in header or f"Segment{n}_Name" in header:
        name = str(header.get(f"Segment{n}_Name", f"segment {n}")).strip() or f"segment {n}"
        try:
            value = int(header.get(f"Segment{n}_LabelValue", 1))
            layer = int(header.get(f"Segment{n}_Layer", 0))
        except ValueError as exc:
            raise LandmarkInputError(f"{path}: Segment{n} has a malformed label or layer") from exc
        if not 0 <= layer < len(layers):
            raise LandmarkInputError(f"{path}: Segment{n}_Layer {layer} is not a layer")
        labels.items.append((name, value, layers[layer] == value, affine))
        n += 1
    if n == 0:
        raise LandmarkInputError(
            f"{path}: no SegmentN_Name fields: not a 3D Slicer segmentation; name it .nrrd "
            "to read it as a labelmap"
        )
    return labels


# --------------------------------------------------------------------------- NIfTI


def read_nifti(path: Path) -> Labels:
    """A NIfTI labelmap (RAS world, converted to LPS): one entry per label value present."""
    import nibabel

    _bounded(path)
    try:
        img: Any = nibabel.load(str(path))
        shape = tuple(int(n) for n in img.shape)
        _check_voxels(path, shape, np.dtype(img.get_data_dtype()).itemsize)
        while len(shape) > 3 and shape[-1] == 1:
            shape = shape[:-1]
        if len(shape) != 3:
            raise LandmarkInputError(f"{path}: expected a 3-D labelmap, got shape {img.shape}")
        data = np.asarray(img.dataobj).reshape(shape)
        affine_ras = np.asarray(img.affine, dtype=np.float64)
    except LandmarkInputError:
        raise
    except Exception as exc:  # nibabel raises many types for bad files
        raise LandmarkInputError(f"{path}: not a readable NIfTI file ({exc})") from exc
    if not np.all(np.isfinite(affine_ras)):
        raise LandmarkInputError(f"{path}: the NIfTI affine is not finite")
    arr = _integer_labels(path, np.ascontiguousarray(data.transpose(2, 1, 0)))
    labels = Labels(path)
    affine = RAS_TO_LPS @ affine_ras
    for value in _values(arr):
        labels.items.append((f"{_stem(path)} label {value}", value, arr, affine))
    return labels


# --------------------------------------------------------------------------- all formats


def _stem(path: Path) -> str:
    name = path.name
    suffix = _suffix(path)
    return name[: -len(suffix)] if name.lower().endswith(suffix) else path.stem


def _values(arr: np.ndarray) -> list[int]:
    values = [int(v) for v in np.unique(arr) if v != 0]
    return values


def read_labels(path: Path) -> Labels:
    """Every labelled mask of a segmentation or labelmap file (not ``.npy``)."""
    suffix = _suffix(path)
    if suffix == ".seg.nrrd":
        return read_seg_nrrd(path)
    if suffix == ".nrrd":
        return read_labelmap_nrrd(path)
    if suffix in (".nii", ".nii.gz"):
        return read_nifti(path)
    if suffix == ".dcm":
        from ctdrill.imaging.plan.dicomseg import read_dicom_seg

        return read_dicom_seg(path)
    raise LandmarkInputError(
        f"{path}: masks are read from .npy, .seg.nrrd, .nrrd, .nii, .nii.gz or DICOM SEG "
        "(.dcm) files"
    )


def mask_landmark(
    path: Path,
    *,
    name: str,
    label: int | None,
    segment: str | None,
    affine_lps: np.ndarray | None,
    margin_mm: float | None,
    source: str,
) -> MaskLandmark:
    """The mask landmark a plan names: ``label`` and/or ``segment`` choose what is taken."""
    _bounded(path)  # a missing file, FIFO or device is named before its suffix
    if _suffix(path) == ".npy":
        if segment is not None:
            raise LandmarkInputError(f"{path}: a .npy labelmap has no named segments; use label")
        mask = load_mask_file(path, label=label)
        return _nonempty(path, name, mask, affine_lps, margin_mm, source, label, None)
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
        mask |= arr.astype(bool) if arr.dtype == np.bool_ else arr == value
    return _nonempty(path, name, mask, first[3], margin_mm, source, label, segment)


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
    source = os.fspath(path.resolve())
    out = []
    empty = []
    for name, value, arr, affine in labels.items:
        mask = arr.astype(bool) if arr.dtype == np.bool_ else arr == value
        if not mask.any():
            empty.append(name)  # Slicer keeps a segment with no voxel: nothing to protect
            continue
        is_seg = _suffix(path) in (".seg.nrrd", ".dcm")
        out.append(
            MaskLandmark(
                name,
                mask,
                affine_lps=affine,
                source=source,
                label=None if is_seg else value,
                segment=name if is_seg else None,
            )
        )
    if not out:
        raise LandmarkInputError(f"{path}: the segmentation holds no labelled voxel")
    warnings: tuple[tuple[str, str], ...] = ()
    if empty:
        names = ", ".join(repr(n) for n in empty)
        warnings = (("segment_empty", f"{path.name}: segments with no voxel skipped: {names}"),)
    return PlanParts(path, (), tuple(out), (), warnings)
