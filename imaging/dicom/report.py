"""A JSON-ready description of a loaded volume (``ctdrill inspect``), and its text form."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ctdrill.imaging.dicom.identity import SHORT_HASH, series_identity
from ctdrill.imaging.dicom.series import SeriesSummary
from ctdrill.imaging.stack import affine_residual_mm
from ctdrill.imaging.volume import CTVolume


def volume_report(
    volume: CTVolume, *, series: Sequence[SeriesSummary] = (), include_phi: bool = False
) -> dict[str, Any]:
    """JSON-ready facts about ``volume`` (no patient identifiers unless ``include_phi``).

    ``series_uid`` is the SHA-256 of the SeriesInstanceUID (as plans record it; the raw UID
    only with ``include_phi``; for a NIfTI, NRRD or MetaImage file the UID is ``sha256:`` + the
    volume's content hash, :func:`ctdrill.imaging.volumes.identity.content_uid`),
    ``series_uid_sha256`` always, ``include_phi`` says which; the
    free-text study and series descriptions (which often hold a name) appear only with
    ``include_phi`` (:mod:`ctdrill.imaging.dicom.identity`).

    Keys: ``dims`` [cols, rows, slices], ``spacing_mm`` [col, row, slice] (slice: the nominal,
    median step), ``affine_lps`` 4x4, ``hu_min`` / ``hu_max`` over valid voxels (None if none is
    valid), ``series_uid``, ``warnings`` [{"code", "message"}], plus ``modality``,
    ``slice_count``, ``is_hu``, ``is_volume``, ``dtype``, ``valid_fraction``,
    ``slice_positions_mm``, ``gantry_tilt_deg``, ``info`` (series provenance) and ``series``
    (every CT stack found).

    Irregular stacks (slice gaps, variable steps): no single affine is true for every slice,
    so ``regular`` is False and ``affine_lps`` is **null**; the geometry is then
    ``slice_origins_lps`` (every slice's voxel (0, 0), i.e. its IPP, LPS mm) plus
    ``voxel_axes_lps`` (the LPS step of one column and of one row, mm): voxel (i, j) of slice k
    is at ``slice_origins_lps[k] + i * voxel_axes_lps[0] + j * voxel_axes_lps[1]``. Both keys
    are given for regular stacks too (then equal to what ``affine_lps`` says), and
    ``affine_residual_mm`` tells how far the nominal-step affine is from the farthest slice.
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
        "affine_lps": (
            [[float(v) for v in row] for row in volume.affine_lps] if volume.regular else None
        ),
        "hu_min": hu_min,
        "hu_max": hu_max,
        **series_identity(info.series_uid, include_phi=include_phi),
        "include_phi": include_phi,
        "warnings": [{"code": w.code, "message": w.message} for w in volume.warnings],
        "modality": info.modality,
        "slice_count": int(hu.shape[0]),
        "is_hu": info.is_hu,
        "is_volume": volume.is_volume,
        "dtype": str(hu.dtype),
        "valid_fraction": n_valid / hu.size,
        "gantry_tilt_deg": round(info.gantry_tilt_deg, 4),
        "slice_positions_mm": [round(float(p), 4) for p in volume.slice_positions_mm],
        "regular": volume.regular,
        "affine_residual_mm": round(affine_residual_mm(volume.slice_positions_mm), 6),
        "slice_origins_lps": [[float(v) for v in o] for o in volume.slice_origins_lps],
        "voxel_axes_lps": [[float(v) for v in volume.affine_lps[:3, c]] for c in (0, 1)],
        "info": {
            "format": info.source_format,
            "manufacturer": info.manufacturer,
            "model": info.model,
            "kvp": info.kvp,
            "kernel": info.kernel,
            "slice_thickness_mm": info.slice_thickness_mm,
            "transfer_syntax": info.transfer_syntax,
            "sop_class_uid": info.sop_class_uid,
            "rescale_type": info.rescale_type,
            "n_files": info.n_files,
            **(
                {
                    "series_description": info.series_description,
                    "study_description": info.study_description,
                }
                if include_phi
                else {}
            ),
        },
        "series": [
            {
                **series_identity(s.series_uid, include_phi=include_phi),
                "slices": s.n_slices,
                "positions": s.n_positions,
                "rows": s.rows,
                "cols": s.cols,
                **({"description": s.description} if include_phi else {}),
                "loaded": s.series_uid == info.series_uid,
            }
            for s in series
        ],
    }


def format_report(report: dict[str, Any]) -> str:
    """A readable multi-line summary of :func:`volume_report`."""
    c, r, s = report["dims"]
    sx, sy, sz = report["spacing_mm"]
    phi = bool(report.get("include_phi"))
    if phi:
        name = report["series_uid"]
    else:
        name = f"{report['series_uid_sha256'][:SHORT_HASH]} (SHA-256 of the UID; --include-phi)"
    fmt = report["info"].get("format", "DICOM")
    source = (
        f"{report['modality']}, {report['info']['n_files']} files"
        if fmt == "DICOM"
        else f"{fmt} file, content hash"
    )
    lines = [
        f"series     {name} ({source})",
        f"dims       {c} cols x {r} rows x {s} slices ({report['dtype']})",
        f"spacing    {sx:g} x {sy:g} x {sz:g} mm (col, row, slice"
        + ("" if report["regular"] else ": the nominal step")
        + ")",
        f"HU range   {report['hu_min']} .. {report['hu_max']} over valid voxels "
        f"({100 * report['valid_fraction']:.1f} % valid)"
        + ("" if report["is_hu"] else " [not HU]"),
    ]
    if report["affine_lps"] is not None:
        lines.append(
            "affine_lps "
            + "\n           ".join(
                "[" + ", ".join(f"{v:10.4f}" for v in row) + "]" for row in report["affine_lps"]
            )
        )
    else:
        lines.append(
            "affine_lps none: irregular slice positions (a single affine would misplace slices "
            f"by up to {report['affine_residual_mm']:.3g} mm); every slice's origin is in "
            "--json slice_origins_lps, sampling uses the true positions"
        )
    if not report["is_volume"]:
        lines.append("NOTE       one slice only: not a volume for the force path")
    if len(report["series"]) > 1:
        lines.append("series found:")
        for item in report["series"]:
            mark = "*" if item["loaded"] else " "
            item_name = item["series_uid"] if phi else item["series_uid_sha256"][:SHORT_HASH]
            lines.append(f"  {mark} {item_name}  {item['slices']} slices")
    if report["warnings"]:
        lines.append("warnings:")
        lines.extend(f"  {w['code']}: {w['message']}" for w in report["warnings"])
    else:
        lines.append("warnings:  none")
    return "\n".join(lines)
