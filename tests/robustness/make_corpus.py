"""Hard-input DICOM corpus: every case is written with pydicom and knows its expected outcome.

``build_corpus(out_dir)`` writes one directory per synthetic case under ``out_dir`` and returns
the synthetic cases followed by the real series of ``../shared/data``. A case expects either a
load (with exactly the listed warning codes, plus any listed as optional) or a refusal
(``ImagingInputError``; the CLI exits 2 with one ``error:`` line). Where two outcomes are both
defensible (a corrupt slice may be skipped *and reported*, or the series refused), the case lists
both alternatives; a silent load or a traceback is never one of them.

Run ``python -m tests.robustness.make_corpus OUT`` to write the corpus for manual inspection.
"""

from __future__ import annotations

import os
import shutil
import struct
import sys
import warnings
import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Literal

import numpy as np
from pydicom.dataelem import DataElement
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
COL_SPACING_MM, ROW_SPACING_MM, SLICE_SPACING_MM = 0.5, 0.6, 1.0
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
    """A sequence nested ``depth`` levels deep (a recursion bomb for naive parsers)."""
    inner = Dataset()
    inner.CodeValue = "X"
    for _ in range(depth):
        item = Dataset()
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


# --------------------------------------------------------------------------------------------
# Synthetic cases. Each builder writes into ``folder`` and returns the acceptable outcomes.
# --------------------------------------------------------------------------------------------

Builder = Callable[[Path], tuple[Expect, ...]]
DIMS = (COLS, ROWS, SLICES)
#: A corrupt slice may be reported and left out (then its place is a gap) or refuse the series.
SKIP_OR_REFUSE_MIDDLE = (
    REFUSE,
    load("files_skipped", "slice_gap", optional=["nonuniform_spacing"]),
)
SKIP_OR_REFUSE_END = (REFUSE, load("files_skipped", dims=(COLS, ROWS, SLICES - 1)))


def _clean(folder: Path) -> tuple[Expect, ...]:
    write_all(base_slices(series="clean"), folder)
    return (load(dims=DIMS),)


def _implicit_vr(folder: Path) -> tuple[Expect, ...]:
    folder.mkdir(parents=True)
    for k, ds in enumerate(base_slices(series="implicit")):
        write(ds, folder / f"{k:03d}.dcm", implicit=True)
    return (load(dims=DIMS),)


def _oblique(folder: Path) -> tuple[Expect, ...]:
    write_all(base_slices(series="oblique", orientation=OBLIQUE_IOP), folder)
    return (load(dims=DIMS),)


def _gantry_tilt(folder: Path) -> tuple[Expect, ...]:
    slices = base_slices(series="tilt", orientation=TILT_IOP)
    for k, ds in enumerate(slices):  # positions step along z, not along the tilted normal
        ds.ImagePositionPatient = [ORIGIN_LPS[0], ORIGIN_LPS[1], ORIGIN_LPS[2] + k]
    write_all(slices, folder)
    return (load("gantry_tilt", dims=DIMS),)


def _truncated_pixels(folder: Path) -> tuple[Expect, ...]:
    paths = write_all(base_slices(series="trunc-pix"), folder)
    middle = paths[SLICES // 2]
    middle.write_bytes(middle.read_bytes()[: -(ROWS * COLS)])  # half the pixel bytes gone
    return SKIP_OR_REFUSE_MIDDLE


def _truncated_header(folder: Path) -> tuple[Expect, ...]:
    slices = base_slices(series="trunc-head")
    paths = write_all(slices, folder)
    last = paths[-1]
    last.write_bytes(last.read_bytes()[:300])  # cut inside the data set header
    return SKIP_OR_REFUSE_END


def _short_pixeldata(folder: Path) -> tuple[Expect, ...]:
    slices = base_slices(series="short-pix")
    slices[SLICES // 2].PixelData = slices[SLICES // 2].PixelData[: ROWS * COLS]
    write_all(slices, folder)
    return SKIP_OR_REFUSE_MIDDLE


def _short_pixeldata_all(folder: Path) -> tuple[Expect, ...]:
    slices = base_slices(series="short-pix-all")
    for ds in slices:
        ds.PixelData = ds.PixelData[:64]
    write_all(slices, folder)
    return (REFUSE,)


def _missing(keyword: str) -> Builder:
    def build(folder: Path) -> tuple[Expect, ...]:
        slices = base_slices(series=f"missing-{keyword}")
        for ds in slices:
            delattr(ds, keyword)
        write_all(slices, folder)
        return (REFUSE,)

    return build


def _missing_ipp_one(folder: Path) -> tuple[Expect, ...]:
    slices = base_slices(series="missing-ipp-one")
    del slices[SLICES // 2].ImagePositionPatient
    write_all(slices, folder)
    return SKIP_OR_REFUSE_MIDDLE


def _bad_value(keyword: str, value: object, vr: str | None = None) -> Builder:
    def build(folder: Path) -> tuple[Expect, ...]:
        slices = base_slices(series=f"bad-{keyword}-{value}")
        for ds in slices:
            if vr is None:
                setattr(ds, keyword, value)
            else:
                ds[keyword] = DataElement(ds[keyword].tag, vr, value)
        write_all(slices, folder)
        return (REFUSE,)

    return build


def _rows_wrong_vr(folder: Path) -> tuple[Expect, ...]:
    slices = base_slices(series="rows-ds")
    for ds in slices:
        ds["Rows"] = DataElement(0x00280010, "DS", str(ROWS))
    write_all(slices, folder)
    return (load(dims=DIMS), REFUSE)


def _slope_wrong_vr(folder: Path) -> tuple[Expect, ...]:
    slices = base_slices(series="slope-fd")
    for ds in slices:
        ds["RescaleSlope"] = DataElement(0x00281053, "FD", 1.0)
    write_all(slices, folder)
    return (load(dims=DIMS), REFUSE)


def _duplicate_identical(folder: Path) -> tuple[Expect, ...]:
    paths = write_all(base_slices(series="dup-same"), folder)
    shutil.copyfile(paths[3], folder / "copy_of_slice.dcm")
    return (load("duplicate_slice", dims=DIMS),)


def _duplicate_conflicting(folder: Path) -> tuple[Expect, ...]:
    slices = base_slices(series="dup-conflict")
    write_all(slices, folder)
    other = base_hu()[3] + 500
    ds = ct_slice(other, slices[3].ImagePositionPatient, series="dup-conflict", instance=99)
    write(ds, folder / "other_at_slice3.dcm")
    return (REFUSE,)


def _gap(folder: Path) -> tuple[Expect, ...]:
    slices = base_slices(series="gap")
    del slices[4]
    write_all(slices, folder)
    return (load("slice_gap", optional=["nonuniform_spacing"]),)


def _nonuniform(folder: Path) -> tuple[Expect, ...]:
    z_mm = [0.0, 1.0, 2.0, 2.7, 3.7, 4.7, 5.7, 6.7]
    write_all(base_slices(series="nonuniform", z_mm=z_mm), folder)
    return (load("nonuniform_spacing", dims=DIMS),)


def _two_series(folder: Path) -> tuple[Expect, ...]:
    write_all(base_slices(series="series-a"), folder / "a")
    write_all(base_slices(series="series-b", hu=base_hu()[:5]), folder / "b")
    return (load("multiple_series", dims=DIMS),)


def _localizer(folder: Path) -> tuple[Expect, ...]:
    write_all(base_slices(series="with-localizer"), folder)
    scout = ct_slice(
        np.zeros((20, 16), np.int16),
        (-40.0, 0.0, 60.0),
        series="with-localizer",
        instance=500,
        orientation=(1.0, 0.0, 0.0, 0.0, 0.0, -1.0),
    )
    scout.ImageType = ["ORIGINAL", "PRIMARY", "LOCALIZER"]
    write(scout, folder / "scout")
    return (load("localizer_dropped", dims=DIMS),)


def _junk_beside(folder: Path) -> tuple[Expect, ...]:
    write_all(base_slices(series="junk-beside"), folder)
    add_junk(folder)
    return (load("files_skipped", dims=DIMS),)


def _junk_only(folder: Path) -> tuple[Expect, ...]:
    add_junk(folder)
    return (REFUSE,)


def _empty_dir(folder: Path) -> tuple[Expect, ...]:
    folder.mkdir(parents=True)
    return (REFUSE,)


def _no_such_dir(folder: Path) -> tuple[Expect, ...]:
    return (REFUSE,)  # never created


def _dicomdir(folder: Path, *, with_images: bool) -> tuple[Expect, ...]:
    from pydicom.fileset import FileSet

    slices = base_slices(series="dicomdir")
    staging = folder.parent / f".{folder.name}-staging"
    paths = write_all(slices, staging)
    fileset = FileSet()
    for path in paths:
        fileset.add(path)
    fileset.write(folder)
    shutil.rmtree(staging)
    if with_images:
        return (load("files_skipped", dims=DIMS), load(dims=DIMS))
    for path in folder.rglob("*"):
        if path.is_file() and path.name != "DICOMDIR":
            path.unlink()
    return (REFUSE,)


def _colour_series(folder: Path) -> tuple[Expect, ...]:
    slices = [
        colour_slice((*ORIGIN_LPS[:2], ORIGIN_LPS[2] + k), series="colour", instance=k)
        for k in range(SLICES)
    ]
    write_all(slices, folder)
    return (REFUSE,)


def _colour_beside(folder: Path) -> tuple[Expect, ...]:
    write_all(base_slices(series="colour-beside"), folder)
    write(colour_slice(ORIGIN_LPS, series="colour-capture", instance=0), folder / "capture")
    return (load("files_skipped", dims=DIMS), load("multiple_series", dims=DIMS))


def _not_hu(folder: Path) -> tuple[Expect, ...]:
    slices = base_slices(series="not-hu")
    for ds in slices:
        ds.RescaleType = "US"
    write_all(slices, folder)
    return (load("not_hu", dims=DIMS),)


def _padding(folder: Path) -> tuple[Expect, ...]:
    hu = base_hu()
    hu[:, :2, :] = -3024  # stored 0xF830 below: outside the scan circle
    slices = base_slices(series="padding", hu=hu)
    for ds in slices:
        ds.PixelPaddingValue = -3024 - int(INTERCEPT)
    write_all(slices, folder)
    return (load("padding", dims=DIMS),)


#: A slice unlike the others may be dropped as a stray (localizer_dropped or files_skipped).
STRAY_OR_REFUSE_MIDDLE = (
    *SKIP_OR_REFUSE_MIDDLE,
    load("localizer_dropped", "slice_gap", optional=["nonuniform_spacing"]),
)


def _mixed_dims(folder: Path) -> tuple[Expect, ...]:
    slices = base_slices(series="mixed-dims")
    odd = ct_slice(np.zeros((ROWS + 2, COLS), np.int16), slices[4].ImagePositionPatient,
                   series="mixed-dims", instance=4)  # fmt: skip
    slices[4] = odd
    write_all(slices, folder)
    return STRAY_OR_REFUSE_MIDDLE


def _mixed_orientation(folder: Path) -> tuple[Expect, ...]:
    slices = base_slices(series="mixed-iop")
    slices[4].ImageOrientationPatient = [0.0, 1.0, 0.0, 1.0, 0.0, 0.0]
    write_all(slices, folder)
    return STRAY_OR_REFUSE_MIDDLE


def _deep_nesting(folder: Path) -> tuple[Expect, ...]:
    slices = base_slices(series="deep-nesting")
    slices[-1].ContentSequence = nested_sequence(1500)
    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(max(limit, 40000))
    try:
        write_all(slices, folder)
    finally:
        sys.setrecursionlimit(limit)
    return (*SKIP_OR_REFUSE_END, load(dims=DIMS))


def _symlink_loop(folder: Path) -> tuple[Expect, ...]:
    write_all(base_slices(series="symlink-loop"), folder)
    (folder / "loop").symlink_to(folder, target_is_directory=True)
    return (load(dims=DIMS), load("files_skipped", dims=DIMS), REFUSE)


def _fifo(folder: Path) -> tuple[Expect, ...]:
    write_all(base_slices(series="fifo"), folder)
    os.mkfifo(folder / "pipe.dcm")  # a named pipe: open() blocks until a writer comes
    return (load(dims=DIMS), load("files_skipped", dims=DIMS))


def _device_links(folder: Path) -> tuple[Expect, ...]:
    write_all(base_slices(series="device-links"), folder)
    (folder / "zero.dcm").symlink_to("/dev/zero")  # endless zeros
    (folder / "random.dcm").symlink_to("/dev/urandom")  # endless noise
    return (load(dims=DIMS), load("files_skipped", dims=DIMS))


def _single_slice(folder: Path) -> tuple[Expect, ...]:
    write_all(base_slices(series="single")[:1], folder)
    return (REFUSE, load("single_slice", dims=(COLS, ROWS, 1)))


def _unknown_vr(folder: Path) -> tuple[Expect, ...]:
    for path in write_all(base_slices(series="unknown-vr"), folder):
        data = bytearray(path.read_bytes())
        at = data.find(b"\x18\x00\x50\x00DS")  # SliceThickness
        data[at + 4 : at + 6] = b"D["  # a VR that does not exist
        path.write_bytes(bytes(data))
    return (REFUSE, load(dims=DIMS))


def _meta_misaligned(folder: Path) -> tuple[Expect, ...]:
    for path in write_all(base_slices(series="meta-misaligned"), folder):
        data = path.read_bytes()
        at = data.find(b"1.2.840.10008.1.2.1\x00") + 17  # inside the transfer syntax value
        path.write_bytes(data[:at] + b"\x00" * 4 + data[at:])
    return (REFUSE,)


def _rle_lossless(folder: Path) -> tuple[Expect, ...]:
    from pydicom.uid import RLELossless

    slices = base_slices(series="rle")
    for ds in slices:
        ds.compress(RLELossless, ds.pixel_array.copy())
    write_all(slices, folder)
    return (load(dims=DIMS),)


def _j2k_lossy(folder: Path) -> tuple[Expect, ...]:
    from pydicom.uid import JPEG2000

    size = 64  # JPEG 2000's default six resolutions need at least 32 x 32 pixels
    slices = []
    for k in range(4):
        hu = ((np.arange(size * size).reshape(size, size) * (k + 3)) % 1500 - 1000).astype(np.int16)
        ds = ct_slice(hu, (*ORIGIN_LPS[:2], ORIGIN_LPS[2] + k), series="j2k-lossy", instance=k)
        ds.compress(JPEG2000, ds.pixel_array.copy(), encoding_plugin="pylibjpeg", j2k_cr=[20])
        ds.LossyImageCompression = "01"
        ds.LossyImageCompressionRatio = 20
        ds.LossyImageCompressionMethod = "ISO_15444_1"
        slices.append(ds)
    write_all(slices, folder)
    return (load("lossy_compression", dims=(size, size, 4)),)


def _transfer_syntax(ts_uid: str) -> Builder:
    def build(folder: Path) -> tuple[Expect, ...]:
        folder.mkdir(parents=True)
        for k, ds in enumerate(base_slices(series=f"ts-{ts_uid}")):
            ds.file_meta.TransferSyntaxUID = UID(ts_uid)
            ds.save_as(
                folder / f"{k:03d}.dcm",
                implicit_vr=False,
                little_endian=True,
                enforce_file_format=True,
            )
        return (REFUSE,)

    return build


def _bomb_rows_cols(folder: Path) -> tuple[Expect, ...]:
    slices = base_slices(series="bomb-rc")
    for ds in slices:
        ds.Rows = 65535
        ds.Columns = 65535
    write_all(slices, folder)
    return (REFUSE,)


def _bomb_frames(folder: Path) -> tuple[Expect, ...]:
    ds = base_slices(series="bomb-frames")[0]
    ds.NumberOfFrames = 2147483647
    write(ds, folder / "multiframe.dcm")
    return (REFUSE,)


def _bomb_element_length(folder: Path) -> tuple[Expect, ...]:
    for path in write_all(base_slices(series="bomb-length"), folder):
        patch_pixel_length(path, 0xFFFFFFF0)
    return (REFUSE,)


def _bomb_one_element_length(folder: Path) -> tuple[Expect, ...]:
    paths = write_all(base_slices(series="bomb-length-one"), folder)
    patch_pixel_length(paths[-1], 0xFFFFFFF0)
    return SKIP_OR_REFUSE_END


def _bomb_header_element_length(folder: Path) -> tuple[Expect, ...]:
    slices = base_slices(series="bomb-header-length")
    for ds in slices:
        ds.add_new(0x00091010, "OB", b"\x00" * 8)  # a private binary element in the header
    for path in write_all(slices, folder):
        patch_pixel_length(path, 0xFFFFFFF0, tag=b"\x09\x00\x10\x10")
    return (REFUSE,)


OBLIQUE_IOP = (0.8, 0.6, 0.0, -0.6, 0.8, 0.0)
TILT_IOP = (1.0, 0.0, 0.0, 0.0, float(np.cos(np.radians(20))), float(np.sin(np.radians(-20))))

#: name -> (builder, fault group, isolate: run only in a capped child process)
SYNTHETIC: dict[str, tuple[Builder, str, bool]] = {
    "clean": (_clean, "none (reference)", False),
    "implicit_vr": (_implicit_vr, "none (implicit VR)", False),
    "oblique": (_oblique, "none (oblique, not sheared)", False),
    "gantry_tilt": (_gantry_tilt, "geometry", False),
    "truncated_pixels": (_truncated_pixels, "truncated file", False),
    "truncated_header": (_truncated_header, "truncated file", False),
    "short_pixeldata": (_short_pixeldata, "short PixelData", False),
    "short_pixeldata_all": (_short_pixeldata_all, "short PixelData", False),
    "missing_ipp": (_missing("ImagePositionPatient"), "missing geometry", False),
    "missing_iop": (_missing("ImageOrientationPatient"), "missing geometry", False),
    "missing_pixel_spacing": (_missing("PixelSpacing"), "missing geometry", False),
    "missing_ipp_one_slice": (_missing_ipp_one, "missing geometry", False),
    "missing_pixeldata": (_missing("PixelData"), "missing pixels", False),
    "zero_pixel_spacing": (_bad_value("PixelSpacing", [0.0, 0.0]), "bad value", False),
    "negative_pixel_spacing": (_bad_value("PixelSpacing", [-0.6, 0.5]), "bad value", False),
    "nan_pixel_spacing": (
        _bad_value("PixelSpacing", "nan\\nan", vr="DS"),
        "bad value",
        False,
    ),
    "inf_position": (
        _bad_value("ImagePositionPatient", "inf\\0\\0", vr="DS"),
        "bad value",
        False,
    ),
    "zero_orientation": (_bad_value("ImageOrientationPatient", [0.0] * 6), "bad value", False),
    "nonorthogonal_orientation": (
        _bad_value("ImageOrientationPatient", [1.0, 0.0, 0.0, 1.0, 0.0, 0.0]),
        "bad value",
        False,
    ),
    "zero_rescale_slope": (_bad_value("RescaleSlope", 0.0), "bad value", False),
    "text_position": (
        _bad_value("ImagePositionPatient", "left\\up\\down", vr="LO"),
        "wrong VR",
        False,
    ),
    "rows_as_ds": (_rows_wrong_vr, "wrong VR", False),
    "slope_as_fd": (_slope_wrong_vr, "wrong VR", False),
    "duplicate_identical": (_duplicate_identical, "duplicates", False),
    "duplicate_conflicting": (_duplicate_conflicting, "duplicates", False),
    "slice_gap": (_gap, "gaps and spacing", False),
    "nonuniform_spacing": (_nonuniform, "gaps and spacing", False),
    "two_series": (_two_series, "two series", False),
    "localizer": (_localizer, "localizer", False),
    "junk_beside_series": (_junk_beside, "junk and non-image files", False),
    "junk_only": (_junk_only, "junk and non-image files", False),
    "empty_dir": (_empty_dir, "junk and non-image files", False),
    "no_such_dir": (_no_such_dir, "junk and non-image files", False),
    "dicomdir_with_images": (
        lambda f: _dicomdir(f, with_images=True),
        "DICOMDIR",
        False,
    ),
    "dicomdir_only": (lambda f: _dicomdir(f, with_images=False), "DICOMDIR", False),
    "colour_series_claiming_hu": (_colour_series, "colour claiming HU", False),
    "colour_capture_beside": (_colour_beside, "colour claiming HU", False),
    "rescale_type_us": (_not_hu, "not HU", False),
    "padding": (_padding, "padding", False),
    "mixed_dims": (_mixed_dims, "inconsistent slices", False),
    "mixed_orientation": (_mixed_orientation, "inconsistent slices", False),
    "rle_lossless": (_rle_lossless, "none (RLE lossless)", False),
    "j2k_lossy": (_j2k_lossy, "lossy compression", False),
    "unknown_vr": (_unknown_vr, "corrupt header", False),
    "meta_misaligned": (_meta_misaligned, "corrupt header", False),
    "unknown_transfer_syntax": (
        _transfer_syntax("1.2.840.10008.1.2.1.99"),
        "transfer syntax",
        False,
    ),
    "private_transfer_syntax": (
        _transfer_syntax("1.2.840.12008.1.2.1"),
        "transfer syntax",
        False,
    ),
    "deep_nesting": (_deep_nesting, "recursion bomb", False),
    "symlink_loop": (_symlink_loop, "file system", False),
    "fifo_in_folder": (_fifo, "file system", True),
    "device_symlinks": (_device_links, "file system", True),
    "single_slice": (_single_slice, "not a volume", False),
    "bomb_rows_cols_65535": (_bomb_rows_cols, "memory bomb", True),
    "bomb_number_of_frames": (_bomb_frames, "memory bomb", True),
    "bomb_pixel_length_all": (_bomb_element_length, "memory bomb", True),
    "bomb_pixel_length_one": (_bomb_one_element_length, "memory bomb", True),
    "bomb_header_element_length": (_bomb_header_element_length, "memory bomb", True),
}

#: Cases whose exact HU and affine are known.
_EXACT: dict[str, tuple[Callable[[], np.ndarray], Callable[[], np.ndarray]]] = {
    "clean": (base_hu, base_affine),
    "implicit_vr": (base_hu, base_affine),
    "rle_lossless": (base_hu, base_affine),
    "oblique": (
        base_hu,
        lambda: base_affine(OBLIQUE_IOP[:3], OBLIQUE_IOP[3:], (0.0, 0.0, SLICE_SPACING_MM)),
    ),
    "gantry_tilt": (base_hu, lambda: base_affine(TILT_IOP[:3], TILT_IOP[3:], (0.0, 0.0, 1.0))),
}


def real_cases(data: Path = SHARED_DATA) -> list[Case]:
    """The real series of ``../shared/data`` with the outcomes its README states."""
    d2n = data / "dicom2nifti_ct_geometry_edgecases"
    single = data / "single_slice_ct"
    # Every real folder holds SOURCE.txt / JSON beside the DICOM files.
    skipped = ["files_skipped"]
    rows: list[tuple[str, Path, tuple[Expect, ...], str]] = [
        (
            "real_ge_head_tilt_varspacing",
            data / "dcmqa_ct_GE_head_gantrytilt_varspacing",
            (load("gantry_tilt", "nonuniform_spacing", "padding", optional=skipped),),
            "real: geometry",
        ),
        (
            "real_philips_mixedfolder",
            data / "dcmqa_ct_Philips_phantom_gantrytilt_mixedfolder",
            (
                load(
                    "multiple_series",
                    "localizer_dropped",
                    "files_skipped",
                    "gantry_tilt",
                    optional=["padding"],
                ),
            ),
            "real: mixed folder",
        ),
        (
            "real_philips_notilt",
            data / "dcmqa_ct_Philips_phantom_notilt_5mm",
            (load(optional=skipped),),
            "real: clean",
        ),
        (
            "real_ge_abdomen_3slice",
            data / "dcmqi_ct_3slice_GE_abdomen",
            (load("padding", optional=skipped),),
            "real: implicit VR, feet first",
        ),
        (
            "real_siemens_tilt_iop_only",
            d2n / "gantrytilting_siemens_14deg",
            (load("gantry_tilt"),),
            "real: geometry",
        ),
        (
            "real_ge_missing_slice",
            d2n / "sliceincrement_ge_missing_slice",
            (load("slice_gap", optional=["nonuniform_spacing"]),),
            "real: geometry",
        ),
        (
            "real_siemens_tilt_missing_slice",
            d2n / "sliceincrement_siemens_tilt_missing_slice",
            (load("gantry_tilt", "slice_gap", optional=["nonuniform_spacing"]),),
            "real: geometry",
        ),
        (
            "real_four_files_one_position",
            d2n / "notavolume_siemens_same_position",
            (REFUSE,),
            "real: not a volume",
        ),
        (
            "real_enhanced_ct_multiframe",
            single / "pydicom_data_repo",
            (load("not_hu", optional=skipped),),
            "real: multi-frame",
        ),
        (
            "real_colour_ct_pictures",
            single / "deid_data_pypi",
            (REFUSE,),
            "real: colour claiming HU",
        ),
        (
            "real_rt_planning_single_slice",
            single / "dicompyler_core",
            (REFUSE, load("single_slice", optional=skipped)),
            "real: not a volume",
        ),
    ]
    return [Case(name, path, expected, fault, real=True) for name, path, expected, fault in rows]


def case_names(*, include_real: bool = True) -> list[str]:
    """Names of the cases :func:`build_corpus` returns, in order, without writing anything."""
    names = [*SYNTHETIC, "two_series_select_b"]
    return names + ([c.name for c in real_cases()] if include_real else [])


def build_corpus(out_dir: Path, *, include_real: bool = True) -> list[Case]:
    """Write every synthetic case under ``out_dir`` and return all cases (synthetic, then real).

    Parameters
    ----------
    out_dir : directory to write into (created; must not hold an older corpus).
    include_real : append the real series of ``../shared/data`` (read in place, not copied).
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    cases: list[Case] = []
    for name, (builder, fault, bomb) in SYNTHETIC.items():
        folder = out_dir / name
        with warnings.catch_warnings():  # pydicom warns about the invalid values we write
            warnings.simplefilter("ignore")
            expected = builder(folder)
        case = Case(name, folder, expected, fault, isolate=bomb)
        if name in _EXACT:
            hu, affine = _EXACT[name]
            case = replace(case, hu=hu(), affine_lps=affine())
        cases.append(case)
    select_b = replace(
        next(c for c in cases if c.name == "two_series"),
        name="two_series_select_b",
        expected=(load(dims=(COLS, ROWS, 5), optional=["multiple_series"]),),
        series_uid=uid("series-b"),
    )
    cases.append(select_b)
    if include_real:
        cases.extend(real_cases())
    return cases


if __name__ == "__main__":
    target = Path(sys.argv[1] if len(sys.argv) > 1 else "robustness-corpus")
    for built in build_corpus(target):
        print(f"{built.name:32s} {' | '.join(e.describe() for e in built.expected)}")
