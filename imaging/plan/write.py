"""Writing plans: the ``ctdrill-plan/1`` document and the 3D Slicer markups document."""

from __future__ import annotations

import json
import os
from typing import Any

import numpy as np

from ctdrill.imaging.plan.curve import POINTS_PER_SEGMENT, slicer_curve
from ctdrill.imaging.plan.landmarks import (
    CanalLandmark,
    LandmarkInputError,
    PointLandmark,
)
from ctdrill.imaging.plan.settings import format_settings
from ctdrill.imaging.plan.slicer import CURVE_POLYLINE
from ctdrill.imaging.plan.types import (
    _SLICER_SCHEMA,
    PLAN_FORMAT,
    SERIES_HASH_KEY,
    Plan,
    PlanInputError,
)


def drills_json(plan: Plan) -> dict[str, Any]:
    """The plan-file key(s) of ``plan``'s drills: ``{"drill": {...}}`` for one drill (today's
    layout), ``{"drills": [{...}, ...]}`` in drilling order for a sequence."""
    if len(plan.drills) == 1:
        return {"drill": plan.drill.to_json()}
    return {"drills": [d.to_json() for d in plan.drills]}


def plan_document(plan: Plan, out_dir: str | os.PathLike[str] | None = None) -> dict[str, Any]:
    """The ``ctdrill-plan/1`` document of ``plan`` (LPS).

    Mask paths are written relative to ``out_dir`` (the folder the plan is saved in), else as
    the landmark's ``source``; a mask's ``label``/``segment`` are kept, and its ``affine_lps``
    only for a ``.npy`` (other files carry their own geometry).
    """
    try:
        lms = [lm.to_plan_item(out_dir) for lm in plan.landmarks]
    except LandmarkInputError as exc:
        raise PlanInputError(str(exc)) from exc
    return {
        "format": PLAN_FORMAT,
        "coordinate_system": "LPS",
        "name": plan.name,
        "entry_mm": plan.entry_lps.tolist(),
        "target_mm": plan.target_lps.tolist(),
        **drills_json(plan),
        "feed_mm_s": plan.feed_mm_s,
        "calibration": plan.calibration,
        "margin_mm": plan.margin_mm,
        "landmarks": lms,
    } | ({} if plan.series_uid_sha256 is None else {SERIES_HASH_KEY: plan.series_uid_sha256})


#: A control point's orientation as Slicer 5 writes it in LPS (identity in RAS).
_ORIENTATION_LPS = [-1.0, -0.0, -0.0, -0.0, -1.0, -0.0, 0.0, 0.0, 1.0]


def _markup(mtype: str, name: str, points: np.ndarray, cps: list[tuple[str, str]]) -> Any:
    """One markup as 3D Slicer 5 writes it (LPS, mm); ``cps`` gives (label, description)."""
    return {
        "type": mtype,
        "name": name,
        "coordinateSystem": "LPS",
        "coordinateUnits": "mm",
        "locked": False,
        "fixedNumberOfControlPoints": False,
        "labelFormat": "%N-%d",
        "lastUsedControlPointNumber": len(points),
        "controlPoints": [
            {
                "id": str(i + 1),
                "label": label,
                "description": desc,
                "associatedNodeID": "",
                "position": [float(v) for v in p],
                "orientation": list(_ORIENTATION_LPS),
                "selected": True,
                "locked": False,
                "visibility": True,
                "positionStatus": "defined",
            }
            for i, (p, (label, desc)) in enumerate(zip(points, cps, strict=True))
        ],
        "measurements": [],
    }


def _curve_control_points(canal: CanalLandmark) -> tuple[np.ndarray, dict[str, Any]]:
    """Control points of the Slicer Curve whose centreline is ``canal``'s, and the setting
    needed: Slicer's spline when the centreline is one (read from a Slicer Curve), else the
    polyline itself with ``curve=polyline`` (Slicer will draw a spline through it, ctdrill
    keeps the straight segments)."""
    pts = canal.points_lps
    n = len(pts)
    if n >= 2 and (n - 1) % POINTS_PER_SEGMENT == 0:
        ctrl = pts[::POINTS_PER_SEGMENT]
        if np.allclose(slicer_curve(ctrl), pts, rtol=0.0, atol=1e-9):
            return ctrl, {}
    if n == 1:
        return pts, {}
    return pts, {"curve": CURVE_POLYLINE}


def markups_document(plan: Plan) -> dict[str, Any]:
    """The 3D Slicer markups document of ``plan`` (LPS, mm).

    Settings go where Slicer keeps them: ``key=value`` words in the first control point's
    description (:mod:`ctdrill.imaging.plan.settings`), so that a file loaded and saved by
    Slicer reads back as the same plan. Mask landmarks cannot be markups and are refused.
    """
    drills = drills_json(plan)
    line = {
        "name": plan.name,
        **(plan.drill.to_json() if "drill" in drills else {"drills": json.dumps(drills["drills"])}),
        "feed_mm_s": plan.feed_mm_s,
        "calibration": plan.calibration,
        "margin_mm": plan.margin_mm,
    } | ({} if plan.series_uid_sha256 is None else {SERIES_HASH_KEY: plan.series_uid_sha256})
    markups = [
        _markup(
            "Line",
            plan.name,
            np.stack([plan.entry_lps, plan.target_lps]),
            [("entry", format_settings(line)), ("target", "")],
        )
    ]
    for lm in plan.landmarks:
        margin = {} if lm.margin_mm is None else {"margin_mm": lm.margin_mm}
        if isinstance(lm, CanalLandmark):
            ctrl, extra = _curve_control_points(lm)
            desc = format_settings({"name": lm.name, "radius_mm": lm.radius_mm, **margin, **extra})
            cps = [(f"{lm.name}-{i + 1}", desc if i == 0 else "") for i in range(len(ctrl))]
            markups.append(_markup("Curve", lm.name, ctrl, cps))
        elif isinstance(lm, PointLandmark):
            desc = format_settings({"name": lm.name, **margin})
            markups.append(_markup("Fiducial", lm.name, lm.point_lps[None], [(lm.name, desc)]))
        else:
            raise PlanInputError(
                f"mask landmark {lm.name!r} cannot be stored in a Slicer markups file; "
                "save the plan as ctdrill-plan/1 JSON"
            )
    return {"@schema": _SLICER_SCHEMA, "markups": markups}
