"""A JSON-ready description of a loaded volume (``ctdrill inspect``), and its text form."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ctdrill.imaging.dicom.series import SeriesSummary
from ctdrill.imaging.volume import CTVolume


def volume_report(volume: CTVolume, *, series: Sequence[SeriesSummary] = ()) -> dict[str, Any]:
    """JSON-ready facts about ``volume`` (no patient identifiers).

    Keys: ``dims`` [cols, rows, slices], ``spacing_mm`` [col, row, slice], ``affine_lps`` 4x4,
    ``hu_min`` / ``hu_max`` over valid voxels (None if none is valid), ``series_uid``,
    ``warnings`` [{"code", "message"}], plus ``modality``, ``slice_count``, ``is_hu``,
    ``is_volume``, ``dtype``, ``valid_fraction``, ``slice_positions_mm``, ``gantry_tilt_deg``,
    ``info`` (series provenance) and ``series`` (every CT stack found).
    """
    hu = volume.hu
    if volume.valid is None:
        vals: np.ndarray = hu
        n_valid = hu.size
    else:
        vals = hu[volume.valid]
        n_valid = int(vals.size)
    hu_min = float(vals.min()) if vals.size else None
    hu_max = float(vals.max()) if vals.size else None
    info = volume.info
    return {
        "dims": list(volume.dims),
        "spacing_mm": [round(s, 6) for s in volume.spacing_mm],
        "affine_lps": [[float(v) for v in row] for row in volume.affine_lps],
        "hu_min": hu_min,
        "hu_max": hu_max,
        "series_uid": info.series_uid,
        "warnings": [{"code": w.code, "message": w.message} for w in volume.warnings],
        "modality": info.modality,
        "slice_count": int(hu.shape[0]),
        "is_hu": info.is_hu,
        "is_volume": volume.is_volume,
        "dtype": str(hu.dtype),
        "valid_fraction": n_valid / hu.size,
        "gantry_tilt_deg": round(info.gantry_tilt_deg, 4),
        "slice_positions_mm": [round(float(p), 4) for p in volume.slice_positions_mm],
        "info": {
            "manufacturer": info.manufacturer,
            "model": info.model,
            "series_description": info.series_description,
            "study_description": info.study_description,
            "kvp": info.kvp,
            "kernel": info.kernel,
            "slice_thickness_mm": info.slice_thickness_mm,
            "transfer_syntax": info.transfer_syntax,
            "sop_class_uid": info.sop_class_uid,
            "rescale_type": info.rescale_type,
            "n_files": info.n_files,
        },
        "series": [
            {
                "series_uid": s.series_uid,
                "slices": s.n_slices,
                "positions": s.n_positions,
                "rows": s.rows,
                "cols": s.cols,
                "description": s.description,
                "loaded": s.series_uid == info.series_uid,
            }
            for s in series
        ],
    }


def format_report(report: dict[str, Any]) -> str:
    """A readable multi-line summary of :func:`volume_report`."""
    c, r, s = report["dims"]
    sx, sy, sz = report["spacing_mm"]
    lines = [
        f"series     {report['series_uid']} ({report['modality']}, {report['info']['n_files']} "
        "files)",
        f"dims       {c} cols x {r} rows x {s} slices ({report['dtype']})",
        f"spacing    {sx:g} x {sy:g} x {sz:g} mm (col, row, slice)",
        f"HU range   {report['hu_min']} .. {report['hu_max']} over valid voxels "
        f"({100 * report['valid_fraction']:.1f} % valid)"
        + ("" if report["is_hu"] else " [not HU]"),
        "affine_lps "
        + "\n           ".join(
            "[" + ", ".join(f"{v:10.4f}" for v in row) + "]" for row in report["affine_lps"]
        ),
    ]
    if not report["is_volume"]:
        lines.append("NOTE       one slice only: not a volume for the force path")
    if len(report["series"]) > 1:
        lines.append("series found:")
        for item in report["series"]:
            mark = "*" if item["loaded"] else " "
            lines.append(f"  {mark} {item['series_uid']}  {item['slices']} slices")
    if report["warnings"]:
        lines.append("warnings:")
        lines.extend(f"  {w['code']}: {w['message']}" for w in report["warnings"])
    else:
        lines.append("warnings:  none")
    return "\n".join(lines)
