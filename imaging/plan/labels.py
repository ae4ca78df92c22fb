"""The labelled masks of one segmentation file, and the size rules every mask reader applies.

Shared by the readers of :mod:`ctdrill.imaging.plan.segmentation` (``.npy``, NRRD, NIfTI,
MetaImage) and :mod:`ctdrill.imaging.plan.dicomseg` (DICOM SEG), below both: a file is checked
to be a regular file of at most :data:`MAX_MASK_FILE_BYTES`, the voxel data its header declares
against :data:`MAX_MASK_BYTES` before anything is allocated, and at most :data:`MAX_SEGMENTS`
segments are read.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ctdrill.imaging.plan.landmark_base import LandmarkInputError
from ctdrill.imaging.volumes.bounded import declared_bytes
from ctdrill.safeio import regular_file_size

#: Largest mask accepted, bytes of voxel data as declared by the file's header.
MAX_MASK_BYTES = 1 << 30
#: Largest segmentation file read, bytes.
MAX_MASK_FILE_BYTES = 1 << 30
#: Most segments (or label values) read from one file (TotalSegmentator writes 117).
MAX_SEGMENTS = 1000


class Labels:
    """The labelled masks of one file: ``(name, label value, array, affine_lps)``.

    The mask of an entry is ``array == value`` (``array`` itself when it is bool), made only
    when asked for; ``named``: the entries are named segments (Slicer, DICOM SEG), not label
    values.
    """

    def __init__(
        self, path: Path, *, named: bool = False, frame_of_reference_uid: str | None = None
    ) -> None:
        self.path = path
        self.named = named
        #: The DICOM Frame of Reference the masks are placed in (a SEG's), None for files
        #: that carry none.
        self.frame_of_reference_uid = frame_of_reference_uid
        self.items: list[tuple[str, int | None, np.ndarray, np.ndarray | None]] = []


def mask_of(arr: np.ndarray, value: int | None) -> np.ndarray:
    """The mask of one entry of :class:`Labels`: ``arr == value``, or ``arr`` when bool."""
    mask: np.ndarray = arr.astype(bool) if arr.dtype == np.bool_ else arr == value
    return mask


def bounded_file_size(path: Path) -> int:
    """The size of the mask file ``path``, bytes: a regular file of at most
    :data:`MAX_MASK_FILE_BYTES`, else refused naming it."""
    size = regular_file_size(path, what="mask file", error=LandmarkInputError)
    if size > MAX_MASK_FILE_BYTES:
        raise LandmarkInputError(
            f"{path}: the mask file holds {size} bytes, more than the {MAX_MASK_FILE_BYTES} "
            "accepted; check that this is the right file"
        )
    return size


def check_mask_voxels(path: Path, shape: tuple[int, ...], itemsize: int, field: str) -> None:
    """Refuse a declared size beyond :data:`MAX_MASK_BYTES` before allocating it."""
    declared_bytes(
        tuple(int(n) for n in shape),
        itemsize,
        max_bytes=MAX_MASK_BYTES,
        where=str(path),
        error=LandmarkInputError,
        field=field,
    )
