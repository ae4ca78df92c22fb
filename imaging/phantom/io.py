"""Write a :class:`~ctdrill.imaging.phantom.mandible.Phantom` as a case folder: DICOM series, plan,
ground truth.

Layout of ``out_dir``::

    ct/                 CT Image Storage series, one file per slice (12-bit unsigned,
                        RescaleIntercept -1024, RescaleType HU), synthetic patient
    plan.json           ctdrill-plan/1, LPS
    ground_truth.json   ctdrill-phantom-truth/1: canal, tissue HU, geometry, safe depth

Everything written is a deterministic function of the phantom's parameters (UIDs derived from
them, no dates), so regenerating a case gives the same bytes.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from pydicom.uid import ExplicitVRLittleEndian, generate_uid

from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.phantom.mandible import (
    AIR_HU,
    CANAL_HU,
    METAL_HU,
    SOFT_TISSUE_HU,
    Phantom,
)
from ctdrill.imaging.phantom.writer import write_series
from ctdrill.imaging.plan.types import SERIES_HASH_KEY, series_uid_hash

PATIENT_NAME = "PHANTOM^MANDIBLE"
TRUTH_FORMAT = "ctdrill-phantom-truth/1"


@dataclass(frozen=True)
class PhantomCase:
    """Paths of a written phantom case."""

    ct_dir: Path
    plan_path: Path
    truth_path: Path
    series_uid: str


def patient_id(phantom: Phantom) -> str:
    """Synthetic PatientID naming the generation parameters, e.g. ``PHANTOM-D2-S0``."""
    return f"PHANTOM-{phantom.misch}-S{phantom.seed}"


def ground_truth(phantom: Phantom) -> dict[str, Any]:
    """The JSON-ready ground truth of ``phantom``."""
    g = phantom.geometry
    geometry = {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(g).items()}
    return {
        "format": TRUTH_FORMAT,
        "coordinate_system": "LPS",
        "misch": phantom.misch,
        "hu": {
            "air": AIR_HU,
            "soft_tissue": SOFT_TISSUE_HU,
            "cortical": g.cortical_hu,
            "trabecular": g.trabecular_hu,
            "canal": CANAL_HU,
            "metal": METAL_HU if g.metal_xy_lps is not None else None,
        },
        "cortical_thickness_mm": phantom.cortical_thickness_mm,
        "canal": {
            "centerline_lps": [[float(v) for v in p] for p in phantom.canal_centerline_lps],
            "radius_mm": phantom.canal_radius_mm,
        },
        "crest_entry_lps": phantom.plan["entry_mm"],
        "planned_depth_mm": float(
            np.linalg.norm(np.subtract(phantom.plan["target_mm"], phantom.plan["entry_mm"]))
        ),
        "max_safe_depth_mm": phantom.max_safe_depth_mm,
        "margin_mm": phantom.plan["margin_mm"],
        "shape": list(phantom.hu.shape),
        "affine_lps": phantom.affine_lps.tolist(),
        "noise_hu": phantom.noise_hu,
        "metal_streak": phantom.metal_streak,
        "seed": phantom.seed,
        "partial_volume": phantom.partial_volume,
        "geometry": geometry,
    }


def write_phantom(
    out_dir: str | Path,
    phantom: Phantom,
    *,
    transfer_syntax: str = ExplicitVRLittleEndian,
) -> PhantomCase:
    """Write ``phantom`` into ``out_dir`` (``ct/``, ``plan.json``, ``ground_truth.json``).

    Parameters
    ----------
    out_dir : str | Path
        Case folder; created if missing. An existing ``ct/`` must be empty (no mixing of series).
    phantom : Phantom
        From :func:`ctdrill.imaging.phantom.mandible.make_mandible_phantom`.
    transfer_syntax : str
        DICOM transfer syntax of the series (default explicit VR little endian).

    Returns
    -------
    PhantomCase
        Where everything went, and the SeriesInstanceUID.
    """
    out = Path(out_dir)
    ct_dir = out / "ct"
    if out.exists() and not out.is_dir():
        raise ImagingInputError(f"{out}: exists and is not a folder; choose another output path")
    if ct_dir.is_dir() and any(ct_dir.iterdir()):
        raise ImagingInputError(
            f"{ct_dir}: already holds files; write the phantom into an empty or new folder"
        )
    params = [
        "ctdrill-phantom",
        phantom.misch,
        repr(phantom.spacing_mm),
        repr(phantom.hu.shape),
        repr(phantom.noise_hu),
        repr(phantom.metal_streak),
        str(phantom.seed),
        *([f"pv{phantom.partial_volume}"] if phantom.partial_volume != 1 else []),
    ]
    series_uid = str(generate_uid(entropy_srcs=[*params, "series"]))
    spacing = phantom.spacing_mm
    written = write_series(
        ct_dir,
        phantom.hu,
        phantom.affine_lps,
        unsigned=True,
        bits_stored=12,
        rescale_intercept=-1024.0,
        rescale_type="HU",
        transfer_syntax=transfer_syntax,
        series_uid=series_uid,
        study_uid=str(generate_uid(entropy_srcs=[*params, "study"])),
        frame_of_reference_uid=str(generate_uid(entropy_srcs=[*params, "for"])),
        patient_name=PATIENT_NAME,
        patient_id=patient_id(phantom),
        series_description=f"Synthetic mandible phantom, Misch {phantom.misch}",
        slice_thickness_mm=spacing[2],
        name_prefix="CT",
        seed=phantom.seed,
        extra={
            "Manufacturer": "ctdrill",
            "ManufacturerModelName": "synthetic mandible phantom",
            "StudyDescription": "ctdrill phantom",
            "BodyPartExamined": "JAW",
            "PatientSex": "O",
            "KVP": "90",
            "ConvolutionKernel": "NONE",
            "WindowCenter": "500",
            "WindowWidth": "3000",
        },
    )
    plan_path = out / "plan.json"
    truth_path = out / "ground_truth.json"
    # The plan records the series it was made on (hashed, never the UID itself).
    plan_doc = {**phantom.plan, SERIES_HASH_KEY: series_uid_hash(written.series_uid)}
    plan_path.write_text(json.dumps(plan_doc, indent=2) + "\n", encoding="utf-8")
    truth_path.write_text(json.dumps(ground_truth(phantom), indent=2) + "\n", encoding="utf-8")
    return PhantomCase(
        ct_dir=ct_dir, plan_path=plan_path, truth_path=truth_path, series_uid=written.series_uid
    )
