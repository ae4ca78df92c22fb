"""What every output says about the calibration set: which one, and how it was obtained.

One owner for the summary fields (export, rehearsal, GUI) and the one terminal/plot line, so an
illustrative set is never mistaken for a measured one and a literature fit says it is one.
"""

from __future__ import annotations

from typing import Any

from ctdrill.model.calibration import Calibration

#: Said when a set has no ``provenance.method`` (sets written before it).
METHOD_NOT_STATED = "not stated by the set (see its source)"


def calibration_fields(cal: Calibration) -> dict[str, Any]:
    """``calibration``, ``calibration_illustrative``, ``calibration_source``,
    ``calibration_method`` and ``calibration_covariance`` (whether it carries one)."""
    return {
        "calibration": cal.name,
        "calibration_illustrative": cal.illustrative,
        "calibration_source": cal.source,
        "calibration_method": cal.method or METHOD_NOT_STATED,
        "calibration_covariance": cal.covariance is not None,
    }


def calibration_line(fields: dict[str, Any]) -> str:
    """``calibration NAME (illustrative): how obtained`` from :func:`calibration_fields`."""
    how = fields.get("calibration_method") or METHOD_NOT_STATED
    if how == METHOD_NOT_STATED:
        how = str(fields.get("calibration_source", how))
    tag = " (illustrative)" if fields.get("calibration_illustrative") else ""
    return f"calibration {fields['calibration']}{tag}: {how}"
