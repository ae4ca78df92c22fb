"""What a loaded series says about itself: its provenance and the loader's warnings.

Values only (no arrays); :mod:`ctdrill.imaging.volume` re-exports them with the volume.
"""

from __future__ import annotations

from dataclasses import dataclass

from ctdrill.warning_codes import LoadWarning as LoadWarning  # the one warning type
from ctdrill.warning_codes import codes

#: Warning codes a load may report (DESIGN.md section 4, plus ``single_slice``): the
#: registry's ``series`` codes (:mod:`ctdrill.warning_codes` gives each one's meaning).
WARNING_CODES: tuple[str, ...] = codes("series")


@dataclass(frozen=True)
class SeriesInfo:
    """Provenance of a loaded series; holds no patient identifiers.

    Attributes
    ----------
    series_uid : str
        SeriesInstanceUID.
    modality : str
        DICOM Modality (``CT`` ...).
    is_hu : bool
        True when the voxel values are Hounsfield units (RescaleType HU or absent on a CT image
        with a rescale); False means calibrate first (:func:`calibrate_grey_to_hu`).
    slice_thickness_mm : float | None
        Nominal SliceThickness: metadata only, never used for geometry.
    n_files : int
        Files that contributed slices to the volume.
    """

    series_uid: str
    modality: str = "CT"
    is_hu: bool = True
    study_description: str = ""
    series_description: str = ""
    manufacturer: str = ""
    model: str = ""
    kvp: float | None = None
    kernel: str = ""
    slice_thickness_mm: float | None = None
    transfer_syntax: str = ""
    sop_class_uid: str = ""
    rescale_type: str = ""
    n_files: int = 0
    gantry_tilt_deg: float = 0.0
    #: True once :func:`ctdrill.imaging.resample_uniform_slices` interpolated an irregular stack.
    resampled: bool = False
    #: The file format the volume was read from: ``DICOM``, ``NIfTI-1``, ``NIfTI-2``, ``NRRD``
    #: or ``MetaImage`` (:func:`ctdrill.imaging.load_ct`).
    source_format: str = "DICOM"
    #: FrameOfReferenceUID of a DICOM series ("" for a file volume, which has none): a DICOM
    #: SEG landmark must share it. Never written to an output.
    frame_of_reference_uid: str = ""
