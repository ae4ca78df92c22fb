"""What discovery finds: one image plane's header, a skipped file, a scan's result; CT SOP classes.

Plain data, filled by :mod:`ctdrill.imaging.dicom.planes` (a header dataset -> planes) and
gathered by :mod:`ctdrill.imaging.dicom.discovery` (files -> headers).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

#: SOP classes that hold CT volumes: CT Image Storage, Enhanced CT, Legacy Converted Enhanced CT.
CT_IMAGE_STORAGE = "1.2.840.10008.5.1.4.1.1.2"
ENHANCED_CT_STORAGE = "1.2.840.10008.5.1.4.1.1.2.1"
LEGACY_ENHANCED_CT_STORAGE = "1.2.840.10008.5.1.4.1.1.2.2"
CT_SOP_CLASSES = (CT_IMAGE_STORAGE, ENHANCED_CT_STORAGE, LEGACY_ENHANCED_CT_STORAGE)
MULTIFRAME_CT_SOP_CLASSES = (ENHANCED_CT_STORAGE, LEGACY_ENHANCED_CT_STORAGE)

#: The uncompressed little-endian transfer syntaxes (the fast header reader's and the pixel
#: reader's own: pydicom is imported only for the others).
EXPLICIT_VR_LITTLE_ENDIAN = "1.2.840.10008.1.2.1"
IMPLICIT_VR_LITTLE_ENDIAN = "1.2.840.10008.1.2"
NATIVE_SYNTAXES = (EXPLICIT_VR_LITTLE_ENDIAN, IMPLICIT_VR_LITTLE_ENDIAN)

#: Transfer syntaxes whose compression loses information.
LOSSY_SYNTAXES = frozenset(
    {
        "1.2.840.10008.1.2.4.50",  # JPEG Baseline
        "1.2.840.10008.1.2.4.51",  # JPEG Extended
        "1.2.840.10008.1.2.4.81",  # JPEG-LS near-lossless
        "1.2.840.10008.1.2.4.91",  # JPEG 2000 (lossy allowed)
        "1.2.840.10008.1.2.4.93",  # JPEG 2000 Part 2 multi-component
        "1.2.840.10008.1.2.4.203",  # HTJ2K (lossy allowed)
    }
)


@dataclass(frozen=True)
class SliceHeader:
    """One image plane (a single-frame file, or one frame of a multi-frame file).

    Geometry is exactly what the header says: ``ipp`` / ``iop`` in LPS mm,
    ``pixel_spacing`` = (row spacing, column spacing) in mm.
    """

    path: Path
    frame: int
    n_frames: int
    series_uid: str
    sop_class_uid: str
    modality: str
    image_type: tuple[str, ...]
    rows: int
    cols: int
    samples_per_pixel: int
    photometric: str
    bits_allocated: int
    bits_stored: int
    pixel_representation: int
    slope: float | None
    intercept: float | None
    rescale_type: str
    ipp: tuple[float, float, float] | None
    iop: tuple[float, float, float, float, float, float] | None
    pixel_spacing: tuple[float, float] | None
    padding_value: int | None
    padding_limit: int | None
    transfer_syntax: str
    lossy: bool
    #: Byte offset of uncompressed little-endian native pixel data (None: decode with pydicom).
    pixel_offset: int | None
    has_pixels: bool
    #: Declared value length of native PixelData (None when encapsulated), and the file size.
    pixel_length: int | None = None
    file_size: int = 0
    meta: dict[str, Any] = field(default_factory=dict, compare=False, hash=False)

    @property
    def frame_bytes(self) -> int:
        """Bytes of one frame of native pixel data."""
        return self.rows * self.cols * self.samples_per_pixel * (self.bits_allocated // 8)


@dataclass(frozen=True)
class Skipped:
    """A DICOM file that holds no CT image plane, and why."""

    path: Path
    reason: str


@dataclass(frozen=True)
class ScanResult:
    """Everything found under a path."""

    headers: tuple[SliceHeader, ...]
    skipped: tuple[Skipped, ...]
    not_dicom: tuple[Path, ...]
    #: Files that could not be opened and folders that could not be listed (permissions).
    unreadable: tuple[Path, ...] = ()
