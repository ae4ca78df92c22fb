"""Write a real DICOM CT series (CT Image Storage) from HU voxels and an LPS affine.

Used for the demo phantom and for analytic geometry tests. The geometry written is exactly the
affine's: ``ImageOrientationPatient`` = unit columns 0 and 1 of the affine (row direction, then
column direction), ``PixelSpacing`` = (row spacing = |column 1|, column spacing = |column 0|),
``ImagePositionPatient`` of slice k = affine @ (0, 0, k, 1) (a sheared k column gives a tilted
stack), or the explicit ``positions_lps`` when given (gaps, duplicates, irregular steps).
"""

from __future__ import annotations

import random
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydicom.dataset import Dataset, FileMetaDataset
from pydicom.uid import (
    PYDICOM_IMPLEMENTATION_UID,
    UID,
    CTImageStorage,
    ExplicitVRLittleEndian,
    ImplicitVRLittleEndian,
    generate_uid,
)

from ctdrill.imaging.errors import ImagingInputError

_UNCOMPRESSED = (ExplicitVRLittleEndian, ImplicitVRLittleEndian)
#: Type 2 (and 2C) attributes of the CT Image IOD that a synthetic series cannot know: written
#: present and empty, as DICOM requires (dciodvfy checks it); ``extra`` may set them.
_TYPE2_UNKNOWN = (
    "PatientBirthDate",
    "PatientSex",
    "StudyDate",
    "StudyTime",
    "ReferringPhysicianName",
    "StudyID",
    "AccessionNumber",
    "PatientPosition",
    "PositionReferenceIndicator",
    "AcquisitionNumber",
    "KVP",
    "Manufacturer",
)


class WriterInputError(ImagingInputError):
    """Arguments that cannot make a valid DICOM series."""


@dataclass(frozen=True)
class WrittenSeries:
    """What :func:`write_series` wrote.

    Attributes
    ----------
    paths : tuple[Path, ...]
        One file per slice, in slice (k) order.
    series_uid, study_uid, frame_of_reference_uid : str
        The UIDs used.
    """

    paths: tuple[Path, ...]
    series_uid: str
    study_uid: str
    frame_of_reference_uid: str


def _fmt_ds(x: float) -> str:
    """A DICOM DS string (at most 16 characters) for ``x``."""
    for digits in range(12, 0, -1):
        s = f"{x:.{digits}g}"
        if len(s) <= 16:
            return s
    raise WriterInputError(f"value {x!r} cannot be written as a DICOM decimal string")


def _store_range(bits_stored: int, unsigned: bool) -> tuple[int, int]:
    if unsigned:
        return 0, 2**bits_stored - 1
    return -(2 ** (bits_stored - 1)), 2 ** (bits_stored - 1) - 1


def write_series(
    out_dir: str | Path,
    hu: np.ndarray,
    affine_lps: np.ndarray,
    *,
    positions_lps: np.ndarray | None = None,
    valid: np.ndarray | None = None,
    rescale_slope: float = 1.0,
    rescale_intercept: float | None = None,
    rescale_type: str | None = None,
    write_rescale: bool = True,
    unsigned: bool = False,
    bits_allocated: int = 16,
    bits_stored: int = 16,
    high_bits_fill: int = 0,
    pixel_padding_value: int | None = None,
    pixel_padding_range_limit: int | None = None,
    transfer_syntax: str = ExplicitVRLittleEndian,
    modality: str = "CT",
    image_type: Sequence[str] = ("ORIGINAL", "PRIMARY", "AXIAL"),
    sop_class_uid: str = CTImageStorage,
    series_uid: str | None = None,
    study_uid: str | None = None,
    frame_of_reference_uid: str | None = None,
    patient_name: str = "Anonymous",
    patient_id: str = "ANON",
    series_description: str = "",
    slice_thickness_mm: float | None = None,
    gantry_tilt_deg: float | None = None,
    instance_numbers: Sequence[int] | None = None,
    name_prefix: str = "IM",
    shuffle_names: bool = False,
    seed: int = 0,
    preamble: bool = True,
    extra: Mapping[str, object] | None = None,
) -> WrittenSeries:
    """Write ``hu`` (slices, rows, cols) as one DICOM file per slice into ``out_dir``.

    Parameters
    ----------
    out_dir : str | Path
        Created if missing.
    hu : np.ndarray
        (slices, rows, cols) HU values.
    affine_lps : np.ndarray
        (4, 4) ``(i=col, j=row, k=slice, 1)`` -> LPS mm; columns 0 and 1 must be orthogonal.
    positions_lps : np.ndarray | None
        (slices, 3) ImagePositionPatient per slice, overriding ``affine @ (0, 0, k, 1)``.
    valid : np.ndarray | None
        (slices, rows, cols) bool; False voxels are written as ``pixel_padding_value``.
    rescale_slope, rescale_intercept : float
        Stored value = round((hu - intercept) / slope). Intercept defaults to -1024 for
        unsigned storage, else 0.
    rescale_type : str | None
        RescaleType tag (e.g. ``"HU"`` or ``"US"``); omitted when None.
    write_rescale : bool
        False omits RescaleSlope/Intercept (stored values are then written as given).
    unsigned, bits_allocated, bits_stored : bool, int, int
        PixelRepresentation 0/1, BitsAllocated (8 or 16), BitsStored (<= BitsAllocated).
    high_bits_fill : int
        Value written into the unused bits above ``bits_stored`` (tests a reader's masking).
    pixel_padding_value, pixel_padding_range_limit : int | None
        Stored padding value (and range limit) tags.
    transfer_syntax : str
        Explicit or implicit VR little endian, or a compressed syntax pydicom can encode
        (RLE Lossless; JPEG 2000 Lossless through pylibjpeg-openjpeg).
    series_uid, study_uid, frame_of_reference_uid : str | None
        Generated (deterministically from ``seed``) when None.
    instance_numbers : Sequence[int] | None
        InstanceNumber per slice; default 1..N in slice order.
    shuffle_names : bool
        File names in a random order unrelated to the slice order.
    preamble : bool
        False writes a bare dataset without preamble, "DICM" or file meta.
    extra : Mapping[str, object] | None
        Further attributes by DICOM keyword, set on every file.

    Returns
    -------
    WrittenSeries
        Paths in slice order and the UIDs.
    """
    vox = np.asarray(hu)
    if vox.ndim != 3 or min(vox.shape) < 1:
        raise WriterInputError(f"hu: expected (slices, rows, cols), got shape {vox.shape}")
    n_slices, n_rows, n_cols = vox.shape
    affine = np.asarray(affine_lps, dtype=np.float64)
    if affine.shape != (4, 4):
        raise WriterInputError(f"affine_lps: expected (4, 4), got {affine.shape}")
    col0, col1, col2 = affine[:3, 0], affine[:3, 1], affine[:3, 2]
    sx, sy = float(np.linalg.norm(col0)), float(np.linalg.norm(col1))
    if sx <= 0 or sy <= 0:
        raise WriterInputError("affine_lps: zero in-plane spacing")
    row_dir, col_dir = col0 / sx, col1 / sy
    if abs(float(row_dir @ col_dir)) > 1e-6:
        raise WriterInputError("affine_lps: columns 0 and 1 must be orthogonal (DICOM IOP)")
    if positions_lps is None:
        ks = np.arange(n_slices, dtype=np.float64)
        ipp = affine[:3, 3][None, :] + ks[:, None] * col2[None, :]
    else:
        ipp = np.asarray(positions_lps, dtype=np.float64)
        if ipp.shape != (n_slices, 3):
            raise WriterInputError(f"positions_lps: expected ({n_slices}, 3), got {ipp.shape}")
    if bits_allocated not in (8, 16) or not 1 <= bits_stored <= bits_allocated:
        raise WriterInputError(
            f"bits: BitsAllocated {bits_allocated} must be 8 or 16 and BitsStored "
            f"{bits_stored} within 1..BitsAllocated"
        )
    if rescale_intercept is None:
        rescale_intercept = -1024.0 if unsigned else 0.0
    if write_rescale:
        stored = np.rint((vox.astype(np.float64) - rescale_intercept) / rescale_slope)
    else:
        stored = vox.astype(np.float64)
    if valid is not None:
        if pixel_padding_value is None:
            raise WriterInputError("valid: needs pixel_padding_value for the padded voxels")
        stored = np.where(np.asarray(valid, dtype=bool), stored, float(pixel_padding_value))
    lo, hi = _store_range(bits_stored, unsigned)
    if stored.min() < lo or stored.max() > hi:
        raise WriterInputError(
            f"hu: stored values {stored.min():.0f}..{stored.max():.0f} do not fit "
            f"{bits_stored} {'unsigned' if unsigned else 'signed'} bits; change the rescale"
        )
    container = {
        (8, True): np.uint8,
        (8, False): np.int8,
        (16, True): np.uint16,
        (16, False): np.int16,
    }[(bits_allocated, unsigned)]
    stored_int: np.ndarray = stored.astype(np.int64)
    if bits_stored < bits_allocated and high_bits_fill:
        raw = stored_int & ((1 << bits_stored) - 1)
        raw |= (int(high_bits_fill) << bits_stored) & ((1 << bits_allocated) - 1)
        stored_int = raw
        if not unsigned:
            stored_int = np.where(
                stored_int >= 2 ** (bits_allocated - 1),
                stored_int - 2**bits_allocated,
                stored_int,
            )
    pixels = stored_int.astype(container)

    rng = random.Random(seed)
    ent = [str(seed), str(vox.shape), name_prefix]
    series_uid = str(series_uid or generate_uid(entropy_srcs=[*ent, "series"]))
    study_uid = str(study_uid or generate_uid(entropy_srcs=[*ent, "study"]))
    frame_of_reference_uid = str(frame_of_reference_uid or generate_uid(entropy_srcs=[*ent, "for"]))
    numbers = (
        list(instance_numbers) if instance_numbers is not None else list(range(1, n_slices + 1))
    )
    if len(numbers) != n_slices:
        raise WriterInputError(f"instance_numbers: expected {n_slices} values")
    names = [f"{name_prefix}{i:05d}.dcm" for i in range(n_slices)]
    if shuffle_names:
        rng.shuffle(names)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    ts = UID(transfer_syntax)
    paths: list[Path] = []
    iop = [_fmt_ds(float(v)) for v in (*row_dir, *col_dir)]
    for k in range(n_slices):
        sop_uid = generate_uid(entropy_srcs=[series_uid, str(k), name_prefix])
        ds = Dataset()
        ds.SOPClassUID = sop_class_uid
        ds.SOPInstanceUID = sop_uid
        ds.PatientName = patient_name
        ds.PatientID = patient_id
        for keyword in _TYPE2_UNKNOWN:
            setattr(ds, keyword, None)  # Type 2: present, empty when unknown
        ds.StudyInstanceUID = study_uid
        ds.SeriesInstanceUID = series_uid
        ds.FrameOfReferenceUID = frame_of_reference_uid
        ds.Modality = modality
        ds.ImageType = list(image_type)
        ds.SeriesDescription = series_description
        ds.SeriesNumber = 1
        ds.InstanceNumber = int(numbers[k])
        ds.ImagePositionPatient = [_fmt_ds(float(v)) for v in ipp[k]]
        ds.ImageOrientationPatient = iop
        ds.PixelSpacing = [_fmt_ds(sy), _fmt_ds(sx)]
        if slice_thickness_mm is not None:
            ds.SliceThickness = _fmt_ds(slice_thickness_mm)
        if gantry_tilt_deg is not None:
            ds.GantryDetectorTilt = _fmt_ds(gantry_tilt_deg)
        ds.SamplesPerPixel = 1
        ds.PhotometricInterpretation = "MONOCHROME2"
        ds.Rows = n_rows
        ds.Columns = n_cols
        ds.BitsAllocated = bits_allocated
        ds.BitsStored = bits_stored
        ds.HighBit = bits_stored - 1
        ds.PixelRepresentation = 0 if unsigned else 1
        if write_rescale:
            ds.RescaleSlope = _fmt_ds(rescale_slope)
            ds.RescaleIntercept = _fmt_ds(rescale_intercept)
        if rescale_type is not None:
            ds.RescaleType = rescale_type
        if pixel_padding_value is not None:
            pad_vr = "US" if unsigned else "SS"
            ds.add_new(0x00280120, pad_vr, int(pixel_padding_value))
            if pixel_padding_range_limit is not None:
                ds.add_new(0x00280121, pad_vr, int(pixel_padding_range_limit))
        for keyword, value in (extra or {}).items():
            setattr(ds, keyword, value)
        if not ds.get("BodyPartExamined") and "Laterality" not in ds:
            # Type 2C: needed (empty: unknown) unless the body part is known to be unpaired.
            ds.Laterality = None
        meta = FileMetaDataset()
        meta.MediaStorageSOPClassUID = UID(sop_class_uid)
        meta.MediaStorageSOPInstanceUID = sop_uid
        meta.ImplementationClassUID = PYDICOM_IMPLEMENTATION_UID
        path = out / names[k]
        if ts in _UNCOMPRESSED:
            data = pixels[k].astype(pixels.dtype.newbyteorder("<")).tobytes()
            ds.PixelData = data + b"\0" * (len(data) % 2)
            meta.TransferSyntaxUID = ts
            ds.file_meta = meta
        else:
            ds.file_meta = meta
            meta.TransferSyntaxUID = ExplicitVRLittleEndian
            try:
                ds.compress(ts, np.ascontiguousarray(pixels[k]), generate_instance_uid=False)
            except (RuntimeError, ValueError, NotImplementedError) as exc:
                raise WriterInputError(
                    f"transfer_syntax: cannot encode {ts.name} here ({exc}); "
                    "use RLE Lossless or an uncompressed syntax"
                ) from exc
        if preamble:
            ds.save_as(path, enforce_file_format=True, implicit_vr=ts == ImplicitVRLittleEndian)
        else:
            del ds.file_meta
            ds.save_as(
                path,
                enforce_file_format=False,
                implicit_vr=ts == ImplicitVRLittleEndian,
                little_endian=True,
            )
        paths.append(path)
    return WrittenSeries(
        paths=tuple(paths),
        series_uid=str(series_uid),
        study_uid=str(study_uid),
        frame_of_reference_uid=str(frame_of_reference_uid),
    )
