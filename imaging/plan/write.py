"""Writing plans: the ``ctdrill-plan/1`` document and the 3D Slicer markups document."""

from __future__ import annotations

from typing import Any

import numpy as np

from ctdrill.imaging.plan.landmarks import (
    CanalLandmark,
    PointLandmark,
)
from ctdrill.imaging.plan.types import (
    _SLICER_SCHEMA,
    PLAN_FORMAT,
    Plan,
    PlanInputError,
)


def plan_document(plan: Plan) -> dict[str, Any]:
    """The ``ctdrill-plan/1`` document of ``plan`` (LPS); mask paths are kept as given."""
    lms: list[dict[str, Any]] = []
    for lm in plan.landmarks:
        item: dict[str, Any] = {"name": lm.name, "kind": lm.kind}
        if isinstance(lm, CanalLandmark):
            item["points_mm"] = lm.points_lps.tolist()
            item["radius_mm"] = lm.radius_mm
        elif isinstance(lm, PointLandmark):
            item["point_mm"] = lm.point_lps.tolist()
        else:
            if not lm.source:
                raise PlanInputError(
                    f"mask landmark {lm.name!r} has no file to refer to; save the mask as .npy "
                    "and set its source"
                )
            item["path"] = lm.source
            if lm.affine_lps is not None:
                item["affine_lps"] = lm.affine_lps.tolist()
        if lm.margin_mm is not None:
            item["margin_mm"] = lm.margin_mm
        lms.append(item)
    d = plan.drill
    return {
        "format": PLAN_FORMAT,
        "coordinate_system": "LPS",
        "name": plan.name,
        "entry_mm": plan.entry_lps.tolist(),
        "target_mm": plan.target_lps.tolist(),
        "drill": {
            "diameter_mm": d.diameter_mm,
            "tip_length_mm": d.tip_length_mm,
            "blades": d.blades,
            "rpm": d.rpm,
        },
        "feed_mm_s": plan.feed_mm_s,
        "calibration": plan.calibration,
        "margin_mm": plan.margin_mm,
        "landmarks": lms,
    }


def _markup(mtype: str, name: str, description: str, points: np.ndarray, labels: list[str]) -> Any:
    return {
        "type": mtype,
        "name": name,
        "description": description,
        "coordinateSystem": "LPS",
        "coordinateUnits": "mm",
        "controlPoints": [
            {"id": str(i + 1), "label": lab, "position": p.tolist()}
            for i, (p, lab) in enumerate(zip(points, labels, strict=True))
        ],
    }


def markups_document(plan: Plan) -> dict[str, Any]:
    """The 3D Slicer markups document of ``plan`` (LPS; settings in descriptions)."""
    d = plan.drill
    line_desc = (
        f"diameter_mm={d.diameter_mm!r} tip_length_mm={d.tip_length_mm!r} blades={d.blades} "
        f"rpm={d.rpm!r} feed_mm_s={plan.feed_mm_s!r} calibration={plan.calibration} "
        f"margin_mm={plan.margin_mm!r}"
    )
    if any(ch.isspace() for ch in plan.calibration):
        raise PlanInputError(
            f"calibration {plan.calibration!r} contains spaces; save the plan as JSON instead"
        )
    markups = [
        _markup(
            "Line",
            plan.name,
            line_desc,
            np.stack([plan.entry_lps, plan.target_lps]),
            ["entry", "target"],
        )
    ]
    for lm in plan.landmarks:
        margin = "" if lm.margin_mm is None else f" margin_mm={lm.margin_mm!r}"
        if isinstance(lm, CanalLandmark):
            pts = lm.points_lps
            labels = [f"{lm.name}-{i + 1}" for i in range(len(pts))]
            desc = f"radius_mm={lm.radius_mm!r}{margin}"
            markups.append(_markup("Curve", lm.name, desc, pts, labels))
        elif isinstance(lm, PointLandmark):
            markups.append(
                _markup("Fiducial", lm.name, margin.strip(), lm.point_lps[None], [lm.name])
            )
        else:
            raise PlanInputError(
                f"mask landmark {lm.name!r} cannot be stored in a Slicer markups file; "
                "save the plan as ctdrill-plan/1 JSON"
            )
    return {"@schema": _SLICER_SCHEMA, "markups": markups}
