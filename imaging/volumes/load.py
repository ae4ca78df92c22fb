"""``load_ct``: a CT volume from a DICOM folder or file, a NIfTI, a NRRD or a MetaImage file.

The format comes from the content (:func:`.sniff.volume_format`); DICOM goes to
:func:`ctdrill.imaging.dicom.series.load_series`, the others to their bounded readers and then
here, where the file's values become a :class:`~ctdrill.imaging.volume.CTVolume`:

- **values**: the stored values with the header's scaling (NIfTI ``scl_slope``/``scl_inter``),
  int16 where that is exact, else float32; non-finite voxels are masked invalid (``padding``).
- **HU or not** (these formats carry no unit for their values; :func:`.hu_values.hu_problem`
  owns the rule): values that never go below 0 (no air at -1000 HU, no fat: grey values
  0..4095, unsigned CBCT grey levels, intensities scaled to 0..1), that span less than
  :data:`MIN_HU_SPAN` (normalised intensities) or whose low tail stays near 0 are not HU:
  warning ``not_hu`` with the hint to map them (``--grey-to-hu``), and ``info.is_hu`` False
  (the force path refuses them until mapped).
- **identity**: ``info.series_uid`` is ``sha256:`` + the SHA-256 of the volume's content
  (:func:`~.identity.content_uid`: its shape, its LPS affine and its HU voxels; for a NIfTI's
  int16 voxels made HU and hashed as they are read, :class:`.identity.HuStream`), so the same
  volume read from any of these formats, or written again with another compression, has one
  identity; as for DICOM, outputs show it hashed once more (``series_uid``) unless
  ``--include-phi``.
- **privacy**: the header's free text (NIfTI ``descrip``, NRRD ``content``) becomes
  ``info.series_description``, which outputs carry only with ``--include-phi``; NRRD key/value
  fields are not kept.
"""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from ctdrill.imaging.provenance import LoadWarning, SeriesInfo
from ctdrill.imaging.resolution import coarse_voxels_warning, volume_sampling_mm
from ctdrill.imaging.volume import CTVolume
from ctdrill.imaging.volumes.grid import TILT_REPORT_DEG
from ctdrill.imaging.volumes.hu_values import LOW_TAIL_PERCENT as LOW_TAIL_PERCENT
from ctdrill.imaging.volumes.hu_values import MIN_HU_LOW_TAIL, hu_problem, low_tail, tail_below
from ctdrill.imaging.volumes.hu_values import MIN_HU_SPAN as MIN_HU_SPAN
from ctdrill.imaging.volumes.identity import content_uid
from ctdrill.imaging.volumes.sniff import read_volume_file, volume_format
from ctdrill.imaging.volumes.types import DEFAULT_MAX_BYTES, VolumeData, VolumeFileError

_INT16 = np.iinfo(np.int16)


def _scaled(path: Path, vol: VolumeData, max_bytes: int) -> np.ndarray:
    """The stored values with the scaling applied: int16 where exact, else float32."""
    stored = vol.data
    slope, inter = vol.scale if vol.scale is not None else (1.0, 0.0)
    if stored.dtype == np.int16 and vol.scale is None:
        return stored
    integral = stored.dtype.kind in "ui" and float(slope).is_integer() and float(inter).is_integer()
    if integral:
        lo, hi = (float(v) for v in (stored.min(), stored.max()))
        ends = sorted((lo * slope + inter, hi * slope + inter))
        integral = _INT16.min <= ends[0] and ends[1] <= _INT16.max
    dtype = np.dtype(np.int16 if integral else np.float32)
    if stored.size * dtype.itemsize > max_bytes:
        raise VolumeFileError(
            f"{path}: the volume needs {stored.size * dtype.itemsize} bytes as HU, more than "
            f"the {max_bytes} accepted; crop or resample it"
        )
    out = np.empty(stored.shape, dtype=dtype)
    work = np.int64 if integral else np.float64
    for k in range(stored.shape[0]):  # one slice at a time: no full-size temporary
        plane = stored[k].astype(work)
        if vol.scale is not None:
            plane = plane * (int(slope) if integral else slope) + (
                int(inter) if integral else inter
            )
        out[k] = plane
    return out


def ct_volume(path: str | Path, vol: VolumeData, *, max_bytes: int = DEFAULT_MAX_BYTES) -> CTVolume:
    """The :class:`CTVolume` of a volume file's data (module docstring)."""
    p = Path(path)
    if vol.data.ndim != 3:
        raise VolumeFileError(f"{p}: expected one 3-D volume, got shape {vol.data.shape}")
    hu = _scaled(p, vol, max_bytes)
    warnings = list(vol.warnings)
    valid = None
    if hu.dtype.kind == "f":
        finite = np.isfinite(hu)
        n_bad = int(finite.size - np.count_nonzero(finite))
        if n_bad == finite.size:
            raise VolumeFileError(f"{p}: no voxel holds a finite value; not a CT volume")
        if n_bad:
            valid = finite
            warnings.append(
                LoadWarning("padding", f"{n_bad} non-finite voxels (NaN or inf) masked invalid")
            )
    values = hu if valid is None else hu[valid]
    sample = None
    if vol.value_range is not None and hu is vol.data:  # measured as it was read
        lo, hi = vol.value_range
        sample = vol.tail_sample
    else:
        lo, hi = float(values.min()), float(values.max())
    problem = hu_problem(lo, hi)
    if problem is None and not tail_below(values, MIN_HU_LOW_TAIL, sample=sample):
        problem = hu_problem(lo, hi, low_tail(values, sample=sample))
    if problem is not None:
        warnings.append(
            LoadWarning(
                "not_hu",
                f"{problem}; map them to HU with --grey-to-hu SLOPE,INTERCEPT or --grey-ref "
                "regions (calibrate_grey_to_hu in Python) before computing forces",
            )
        )
    if vol.tilt_deg > TILT_REPORT_DEG:
        warnings.append(
            LoadWarning(
                "gantry_tilt",
                f"slices are sheared by {vol.tilt_deg:.2f} deg from the slice normal; the affine "
                "keeps the shear",
            )
        )
    if hu.shape[0] == 1:
        warnings.append(
            LoadWarning("single_slice", "one slice only: not a volume for the force path")
        )
    scaled = vol.scale is not None or vol.scaled
    info = SeriesInfo(
        series_uid=vol.content_uid
        if vol.content_uid is not None and hu is vol.data
        else content_uid(hu, vol.affine_lps),
        modality="",
        is_hu=problem is None,
        series_description=vol.description,
        rescale_type=("scl_slope/scl_inter" if scaled else "")
        if vol.format.startswith("NIfTI")
        else "",
        n_files=1,
        gantry_tilt_deg=vol.tilt_deg,
        source_format=vol.format,
    )
    volume = CTVolume(hu=hu, affine_lps=vol.affine_lps, valid=valid, info=info)
    coarse = coarse_voxels_warning(*volume_sampling_mm(volume))  # the DICOM loader's rule
    return replace(volume, warnings=(*warnings, *(() if coarse is None else (coarse,))))


#: Names of volume files, for the hint when a folder given as a DICOM series holds one.
_VOLUME_SUFFIXES = (".nii", ".nii.gz", ".nrrd", ".nhdr", ".mha", ".mhd")
#: Folder entries looked at for that hint.
_HINT_ENTRIES = 1000


def _volume_file_in(folder: Path) -> str | None:
    """The name of a volume file at the top of ``folder`` (a few entries looked at), or None."""
    if not folder.is_dir():
        return None
    try:
        with os.scandir(folder) as entries:
            for n, entry in enumerate(entries):
                if n >= _HINT_ENTRIES:
                    break
                if entry.name.lower().endswith(_VOLUME_SUFFIXES) and entry.is_file():
                    return entry.name
    except OSError:
        return None
    return None


def listed_series(path: str | Path, volume: CTVolume) -> tuple[Any, ...]:
    """What ``ctdrill inspect`` lists: every DICOM series under ``path``, or the file's one
    volume (``SeriesSummary`` of :mod:`ctdrill.imaging.dicom.series`)."""
    from ctdrill.imaging.dicom.series import SeriesSummary, list_series

    if volume.info.source_format == "DICOM":
        return list_series(path)
    slices, rows, cols = volume.hu.shape
    return (SeriesSummary(volume.info.series_uid, slices, slices, rows, cols, ""),)


def load_ct(
    path: str | Path, *, series_uid: str | None = None, max_bytes: int = DEFAULT_MAX_BYTES
) -> CTVolume:
    """Load a CT from a DICOM folder or file, a NIfTI, NRRD or MetaImage file (by content).

    Parameters
    ----------
    path : a DICOM folder (searched recursively) or file, ``.nii``/``.nii.gz``,
        ``.nrrd``/``.nhdr`` or ``.mha``/``.mhd`` (the name does not decide).
    series_uid : for DICOM, the series to load (UID or its hash); for a file, when given it
        must name the file's one volume (its content identity or that identity's hash).
    max_bytes : refuse when the voxels would need more than this, bytes (checked before
        anything is allocated or inflated).

    Returns
    -------
    CTVolume
        ``hu`` (slices, rows, cols), ``affine_lps`` exact, warnings as :func:`load_series`.

    Raises
    ------
    ImagingInputError
        One message naming the file and the field: unknown format, damaged or ambiguous
        geometry, 4-D, sizes beyond ``max_bytes`` or beyond what the file holds.
    """
    kind = volume_format(path, error=VolumeFileError)
    if kind == "dicom":
        from ctdrill.imaging.dicom.series import SeriesInputError, load_series

        try:
            return load_series(path, series_uid=series_uid, max_bytes=max_bytes)
        except SeriesInputError as exc:
            hint = _volume_file_in(Path(path))
            if hint is None:
                raise
            raise VolumeFileError(f"{exc}; the folder holds {hint}: give the file itself") from exc
    vol = read_volume_file(
        path, max_bytes=max_bytes, error=VolumeFileError, kind=kind, identity=True
    )
    volume = ct_volume(path, vol, max_bytes=max_bytes)
    if series_uid is not None:
        from ctdrill.imaging.dicom.identity import matches_series, series_label

        if not matches_series(series_uid, volume.info.series_uid):
            raise VolumeFileError(
                f"{path}: series {series_uid} not found: the file holds one volume, "
                f"{series_label(volume.info.series_uid)}"
            )
    return volume
