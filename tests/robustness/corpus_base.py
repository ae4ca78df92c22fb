"""Building blocks of the hard-input corpus: outcomes, cases and a synthetic CT series.

The base series is 8 slices of 12 x 10 voxels (0.4 mm rows, 0.5 mm columns, 1 mm slices: not
coarse) with a distinct HU per voxel, written with pydicom (CT Image Storage, explicit VR little
endian) under names unrelated to the slice order and InstanceNumbers against it.
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
from pydicom.dataset import Dataset, FileMetaDataset
from pydicom.sequence import Sequence as DicomSequence
from pydicom.uid import (
    PYDICOM_IMPLEMENTATION_UID,
    UID,
    CTImageStorage,
    ExplicitVRLittleEndian,
    ImplicitVRLittleEndian,
    SecondaryCaptureImageStorage,
    generate_uid,
)

ROOT = Path(__file__).resolve().parents[2]
SHARED_DATA = ROOT.parent / "shared" / "data"

#: Identifiers written into every synthetic slice; no output may contain them (privacy tests).
PHI: dict[str, str] = {
    "PatientName": "Quarantotto^Ermenegilda",
    "PatientID": "PID-73395121",
    "PatientBirthDate": "19540817",
    "AccessionNumber": "ACC-55190342",
    "InstitutionName": "Ospedale Zanzibar Nord",
    "ReferringPhysicianName": "Fitzwilliam^Oberon",
}

#: Geometry of the synthetic base series.
COLS, ROWS, SLICES = 10, 12, 8
COL_SPACING_MM, ROW_SPACING_MM, SLICE_SPACING_MM = 0.5, 0.4, 1.0
ORIGIN_LPS = (-20.0, -30.0, 40.0)
INTERCEPT = -1024.0

Outcome = Literal["load", "refuse"]


@dataclass(frozen=True)
class Expect:
    """One acceptable outcome of loading a case.

    Attributes
    ----------
    outcome : "load" or "refuse" (``ImagingInputError``, CLI exit 2).
    codes : warning codes that must all be present on a load.
    optional : warning codes that may also be present on a load.
    dims : expected ``(cols, rows, slices)`` on a load, or None to skip the check.
    """

    outcome: Outcome
    codes: frozenset[str] = frozenset()
    optional: frozenset[str] = frozenset()
    dims: tuple[int, int, int] | None = None

    def accepts_load(self, codes: Sequence[str], dims: Sequence[int]) -> bool:
        """True if a load with warning ``codes`` and ``dims`` (cols, rows, slices) matches."""
        got = set(codes)
        if self.outcome != "load" or not self.codes <= got or not got <= self.codes | self.optional:
            return False
        return self.dims is None or tuple(int(d) for d in dims) == self.dims

    def describe(self) -> str:
        """Short human-readable form, e.g. ``load [slice_gap] (+nonuniform_spacing?)``."""
        if self.outcome == "refuse":
            return "refuse (exit 2)"
        text = "load " + ("[" + ", ".join(sorted(self.codes)) + "]" if self.codes else "clean")
        if self.optional:
            text += " (+" + ", ".join(sorted(self.optional)) + "?)"
        return text


REFUSE = Expect("refuse")


def load(
    *codes: str, optional: Sequence[str] = (), dims: tuple[int, int, int] | None = None
) -> Expect:
    """An expected load with exactly ``codes`` (plus any of ``optional``)."""
    return Expect("load", frozenset(codes), frozenset(optional), dims)


@dataclass(frozen=True, eq=False)
class Case:
    """One hard input and what a correct loader does with it.

    Attributes
    ----------
    name : short identifier (also the directory name of a synthetic case).
    path : directory handed to ``load_series`` / ``ctdrill inspect``.
    expected : acceptable outcomes; the first is the preferred one.
    fault : which fault the case injects (the robustness report groups by it).
    isolate : a resource hazard (memory bomb, special file that may block): run only in a
        child process under an address-space limit and a timeout.
    series_uid : passed as ``series_uid=`` / ``--series`` when set.
    hu : exact expected HU volume (slices, rows, cols) on a load, when known.
    affine_lps : exact expected (4, 4) affine on a load, when known.
    real : True for the real series of ``../shared/data``.
    """

    name: str
    path: Path
    expected: tuple[Expect, ...]
    fault: str
    isolate: bool = False
    series_uid: str | None = None
    hu: np.ndarray | None = field(default=None, repr=False)
    affine_lps: np.ndarray | None = field(default=None, repr=False)
    real: bool = False


def uid(*parts: object) -> str:
    """A deterministic UID from ``parts`` (the corpus is reproducible byte for byte)."""
    return str(generate_uid(entropy_srcs=[str(p) for p in parts]))


def base_hu() -> np.ndarray:
    """HU of the base series, (slices, rows, cols) int16: distinct per voxel, -1000..1400."""
    k, j, i = np.meshgrid(
        np.arange(SLICES), np.arange(ROWS), np.arange(COLS), indexing="ij"
    )  # fmt: skip
    return (-1000 + 20 * i + 100 * j + 30 * k).astype(np.int16)


def base_affine(
    row_dir: Sequence[float] = (1.0, 0.0, 0.0),
    col_dir: Sequence[float] = (0.0, 1.0, 0.0),
    slice_step_lps: Sequence[float] = (0.0, 0.0, SLICE_SPACING_MM),
) -> np.ndarray:
    """Affine (i=col, j=row, k=slice, 1) -> LPS mm of a series written by :func:`ct_slice`."""
    affine = np.eye(4)
    affine[:3, 0] = np.asarray(row_dir) * COL_SPACING_MM
    affine[:3, 1] = np.asarray(col_dir) * ROW_SPACING_MM
    affine[:3, 2] = slice_step_lps
    affine[:3, 3] = ORIGIN_LPS
    return affine


def ct_slice(
    hu: np.ndarray,
    position_lps: Sequence[float],
    *,
    series: str,
    instance: int,
    orientation: Sequence[float] = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0),
    study: str = "study",
) -> Dataset:
    """A complete CT Image Storage slice (explicit VR little endian) holding ``hu`` (rows, cols)."""
    ds = Dataset()
    ds.file_meta = FileMetaDataset()
    ds.file_meta.MediaStorageSOPClassUID = CTImageStorage
    sop = uid(series, instance, *position_lps)
    ds.file_meta.MediaStorageSOPInstanceUID = UID(sop)
    ds.file_meta.TransferSyntaxUID = UID(ExplicitVRLittleEndian)
    ds.file_meta.ImplementationClassUID = PYDICOM_IMPLEMENTATION_UID
    ds.SOPClassUID = CTImageStorage
    ds.SOPInstanceUID = sop
    for key, value in PHI.items():
        setattr(ds, key, value)
    ds.Modality = "CT"
    ds.ImageType = ["ORIGINAL", "PRIMARY", "AXIAL"]
    ds.StudyInstanceUID = uid(study)
    ds.SeriesInstanceUID = uid(series)
    ds.FrameOfReferenceUID = uid(study, "frame")
    ds.StudyDate = "20240115"
    ds.StudyTime = "101500"
    ds.StudyID = "1"
    ds.SeriesNumber = 3
    ds.InstanceNumber = 1000 - instance  # against the slice order on purpose
    ds.ImagePositionPatient = [float(v) for v in position_lps]
    ds.ImageOrientationPatient = [float(v) for v in orientation]
    ds.PixelSpacing = [ROW_SPACING_MM, COL_SPACING_MM]
    ds.SliceThickness = SLICE_SPACING_MM
    ds.KVP = 120
    ds.SamplesPerPixel = 1
    ds.PhotometricInterpretation = "MONOCHROME2"
    ds.Rows, ds.Columns = int(hu.shape[0]), int(hu.shape[1])
    ds.BitsAllocated = 16
    ds.BitsStored = 16
    ds.HighBit = 15
    ds.PixelRepresentation = 1
    ds.RescaleIntercept = INTERCEPT
    ds.RescaleSlope = 1.0
    ds.RescaleType = "HU"
    ds.WindowCenter = 40
    ds.WindowWidth = 400
    ds.PixelData = (hu.astype(np.int32) - int(INTERCEPT)).astype("<i2").tobytes()
    return ds


def base_slices(
    *,
    series: str,
    hu: np.ndarray | None = None,
    z_mm: Sequence[float] | None = None,
    orientation: Sequence[float] = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0),
    study: str = "study",
) -> list[Dataset]:
    """The base series: one :func:`ct_slice` per slice, slice k at ``z_mm[k]`` above the origin."""
    volume = base_hu() if hu is None else hu
    zs = [k * SLICE_SPACING_MM for k in range(volume.shape[0])] if z_mm is None else list(z_mm)
    normal = np.cross(orientation[:3], orientation[3:])
    return [
        ct_slice(
            volume[k],
            [float(v) for v in np.asarray(ORIGIN_LPS) + zs[k] * normal],
            series=series,
            instance=k,
            orientation=orientation,
            study=study,
        )
        for k in range(volume.shape[0])
    ]


def write(ds: Dataset, path: Path, *, implicit: bool = False) -> Path:
    """Write ``ds`` as a DICOM Part 10 file (preamble + meta) at ``path``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if implicit:
        ds.file_meta.TransferSyntaxUID = UID(ImplicitVRLittleEndian)
    ds.save_as(path, enforce_file_format=True)
    return path


def write_all(datasets: Sequence[Dataset], folder: Path) -> list[Path]:
    """Write the slices into ``folder`` under names unrelated to their order; return the paths."""
    folder.mkdir(parents=True, exist_ok=True)
    return [write(ds, folder / f"IM{(k * 7919) % 1000:04d}") for k, ds in enumerate(datasets)]


def png_bytes(width: int = 4, height: int = 3) -> bytes:
    """A valid greyscale PNG (built with zlib: no imaging library)."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    raw = b"".join(b"\x00" + bytes(range(width)) for _ in range(height))
    header = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", header)
        + chunk(b"IDAT", zlib.compress(raw))
        + chunk(b"IEND", b"")
    )


def add_junk(folder: Path) -> None:
    """Non-DICOM files found in real exports: text, PNG, an empty file, random bytes, JSON."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "README.txt").write_text("exported by a PACS\n")
    (folder / "preview.png").write_bytes(png_bytes())
    (folder / "empty.dcm").write_bytes(b"")
    (folder / "random.dcm").write_bytes(np.random.default_rng(7).bytes(4096))
    (folder / "meta.json").write_text('{"not": "dicom"}')
    (folder / "fake_preamble.dcm").write_bytes(b"\x00" * 128 + b"DICM" + b"\xff" * 40)


def colour_slice(position_lps: Sequence[float], *, series: str, instance: int) -> Dataset:
    """An 8-bit RGB secondary-capture 'CT' carrying rescale tags (a colour picture, not HU)."""
    rgb = np.zeros((ROWS, COLS, 3), np.uint8)
    rgb[..., 0] = 200
    ds = ct_slice(base_hu()[0], position_lps, series=series, instance=instance)
    ds.file_meta.MediaStorageSOPClassUID = SecondaryCaptureImageStorage
    ds.SOPClassUID = SecondaryCaptureImageStorage
    ds.ImageType = ["DERIVED", "SECONDARY"]
    ds.SamplesPerPixel = 3
    ds.PhotometricInterpretation = "RGB"
    ds.PlanarConfiguration = 0
    ds.BitsAllocated = 8
    ds.BitsStored = 8
    ds.HighBit = 7
    ds.PixelRepresentation = 0
    ds.PixelData = rgb.tobytes()
    return ds


def nested_sequence(depth: int) -> DicomSequence:
    """A sequence nested ``depth`` levels deep (a recursion bomb for naive parsers).

    Each item is marked as already in the file's encoding (explicit VR, little endian): pydicom
    then checks the tree for ambiguous VRs once from the top instead of again under every
    level (quadratic: 3.4 s of CPU at 1500 levels, 0.07 s so); the bytes written are the same.
    """

    def new_item() -> Dataset:
        item = Dataset()
        item.set_original_encoding(False, True, item._character_set)
        return item

    inner = new_item()
    inner.CodeValue = "X"
    for _ in range(depth):
        item = new_item()
        item.ContentSequence = DicomSequence([inner])
        inner = item
    return DicomSequence([inner])


def patch_pixel_length(path: Path, new_length: int, *, tag: bytes = b"\xe0\x7f\x10\x00") -> None:
    """Rewrite the declared length of an OB/OW element (PixelData) of an explicit-VR file."""
    data = bytearray(path.read_bytes())
    at = data.rfind(tag)
    assert at > 0 and data[at + 4 : at + 6] in (b"OW", b"OB"), path
    data[at + 8 : at + 12] = struct.pack("<I", new_length)
    path.write_bytes(bytes(data))
