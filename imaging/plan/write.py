"""Writing plans: the ``ctdrill-plan/1`` document and the 3D Slicer markups document.

The entry points: :func:`save_plan`, :func:`write_plans` (files, atomically),
:func:`plan_to_dict` and :func:`plan_to_markups` (documents).
"""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from ctdrill.imaging.plan.arch import ARCH_MARKUP_NAME, ARCH_ROLE
from ctdrill.imaging.plan.budget import DEFAULT_PLACEMENT
from ctdrill.imaging.plan.curve import POINTS_PER_SEGMENT, slicer_curve
from ctdrill.imaging.plan.landmarks import (
    CanalLandmark,
    LandmarkInputError,
    PointLandmark,
)
from ctdrill.imaging.plan.settings import format_settings
from ctdrill.imaging.plan.slicer import (
    CURVE_POLYLINE,
    IMPLANT_DRILLS_SETTING,
    IMPLANT_SETTINGS,
    MAX_CURVE_POINTS,
)
from ctdrill.imaging.plan.types import (
    _SLICER_SCHEMA,
    MAX_TRAJECTORIES,
    PLAN_FORMAT,
    SERIES_HASH_KEY,
    Plan,
    PlanInputError,
    series_uid_hash,
)


def drills_json(plan: Plan) -> dict[str, Any]:
    """The plan-file key(s) of ``plan``'s drills: ``{"drill": {...}}`` for one drill (today's
    layout), ``{"drills": [{...}, ...]}`` in drilling order for a sequence."""
    if len(plan.drills) == 1:
        return {"drill": plan.drill.to_json()}
    return {"drills": [d.to_json() for d in plan.drills]}


def _shared(plans: tuple[Plan, ...]) -> Plan:
    """The first plan, after checking that every plan shares its landmarks, arch and series
    (a file holds one set of each) and that names are unique."""
    if not plans:
        raise PlanInputError("no trajectory to write; a plan file holds at least one")
    if len(plans) > MAX_TRAJECTORIES:
        raise PlanInputError(
            f"{len(plans)} trajectories to write, more than the {MAX_TRAJECTORIES} a plan may "
            "hold; split the case into several plans"
        )
    first = plans[0]
    names: set[str] = set()
    for p in plans:
        if p.name in names:
            raise PlanInputError(
                f"two trajectories are named {p.name!r}; name each trajectory once"
            )
        names.add(p.name)
        if p is first:
            continue
        same_lms = len(p.landmarks) == len(first.landmarks) and all(
            a.kind == b.kind and a.name == b.name and a.margin_mm == b.margin_mm and a.same_shape(b)
            for a, b in zip(p.landmarks, first.landmarks, strict=True)
        )
        if not same_lms:
            raise PlanInputError(
                f"trajectories {first.name!r} and {p.name!r} protect different landmarks; one "
                "plan file holds one set of landmarks shared by all its trajectories"
            )
        a, b = p.arch_lps, first.arch_lps
        if (a is None) != (b is None) or (
            a is not None and b is not None and not np.array_equal(a, b)
        ):
            raise PlanInputError(
                f"trajectories {first.name!r} and {p.name!r} have different dental arches; "
                "one plan file holds one arch"
            )
        if p.series_uid_sha256 != first.series_uid_sha256:
            raise PlanInputError(
                f"trajectories {first.name!r} and {p.name!r} were made on different series "
                "(their series hashes differ); write them to separate files"
            )
    return first


def _trajectory_json(plan: Plan) -> dict[str, Any]:
    """The trajectory keys of ``plan`` (entry, target as drawn, drills, implant, settings)."""
    return {
        "entry_mm": plan.entry_lps.tolist(),
        "target_mm": plan.planned_target_lps.tolist(),
        **drills_json(plan),
        **({} if plan.implant is None else {"implant": plan.implant.to_json()}),
        "feed_mm_s": plan.feed_mm_s,
        "calibration": plan.calibration,
        "margin_mm": plan.margin_mm,
        "min_wall_mm": plan.min_wall_mm,
        **({} if plan.site is None else {"site": plan.site}),
        **({} if plan.placement == DEFAULT_PLACEMENT else {"placement": plan.placement}),
    }


def plan_document(plan: Plan, out_dir: str | os.PathLike[str] | None = None) -> dict[str, Any]:
    """The ``ctdrill-plan/1`` document of ``plan`` (LPS); see :func:`plans_document`."""
    return plans_document((plan,), out_dir)


def plans_document(
    plans: tuple[Plan, ...], out_dir: str | os.PathLike[str] | None = None
) -> dict[str, Any]:
    """The ``ctdrill-plan/1`` document of ``plans`` (LPS): one trajectory in the single form
    (``entry_mm``, ``target_mm``, ... at the top level), several in ``trajectories``; the
    landmarks, the arch and the series hash once, shared.

    Mask paths are written relative to ``out_dir`` (the folder the plan is saved in), else as
    the landmark's ``source``; a mask's ``label``/``segment`` are kept, and its ``affine_lps``
    only for a ``.npy`` (other files carry their own geometry).
    """
    first = _shared(plans)
    try:
        lms = [lm.to_plan_item(out_dir) for lm in first.landmarks]
    except LandmarkInputError as exc:
        raise PlanInputError(str(exc)) from exc
    head: dict[str, Any] = {"format": PLAN_FORMAT, "coordinate_system": "LPS"}
    if len(plans) == 1:
        head |= {"name": first.name, **_trajectory_json(first)}
    else:
        head["trajectories"] = [{"name": p.name, **_trajectory_json(p)} for p in plans]
    head["landmarks"] = lms
    if first.arch_lps is not None:
        head["arch_mm"] = first.arch_lps.tolist()
    if first.series_uid_sha256 is not None:
        head[SERIES_HASH_KEY] = first.series_uid_sha256
    return head


def write_plan_file(plans: tuple[Plan, ...], path: Path) -> None:
    """Write ``plans`` to ``path`` atomically (aside, then renamed): Slicer markups for a
    ``.mrk.json``, else ``ctdrill-plan/1``."""
    if path.name.lower().endswith(".mrk.json"):
        doc = markups_document(plans)
    else:
        doc = plans_document(plans, out_dir=path.parent)
    text = json.dumps(doc, indent=2) + "\n"
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent or ".")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


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


def _curve_control_points(pts: np.ndarray) -> tuple[np.ndarray, dict[str, Any]]:
    """Control points of the Slicer Curve whose polyline is ``pts`` (a canal's centreline,
    the arch), and the setting needed: Slicer's spline when the polyline is one (read from a
    Slicer Curve), else the polyline itself with ``curve=polyline`` (Slicer will draw a
    spline through it, ctdrill keeps the straight segments)."""
    n = len(pts)
    if n >= 2 and (n - 1) % POINTS_PER_SEGMENT == 0:
        ctrl = pts[::POINTS_PER_SEGMENT]
        if np.allclose(slicer_curve(ctrl), pts, rtol=0.0, atol=1e-9):
            return ctrl, {}
    if n == 1:
        return pts, {}
    return pts, {"curve": CURVE_POLYLINE}


def _line_settings(plan: Plan) -> dict[str, Any]:
    """The Line's settings: name, drills, implant, feed, calibration, margin, wall, site,
    series."""
    drills = drills_json(plan)
    implant = {} if plan.implant is None else plan.implant.to_json()
    protocol = (
        {IMPLANT_DRILLS_SETTING: json.dumps(implant["drills"])} if "drills" in implant else {}
    )
    return (
        {
            "name": plan.name,
            **(
                plan.drill.to_json()
                if "drill" in drills
                else {"drills": json.dumps(drills["drills"])}
            ),
        }
        | {key: implant[field] for key, field in IMPLANT_SETTINGS.items() if implant}
        | protocol
        | {
            "feed_mm_s": plan.feed_mm_s,
            "calibration": plan.calibration,
            "margin_mm": plan.margin_mm,
            "min_wall_mm": plan.min_wall_mm,
        }
        | ({} if plan.site is None else {"site": plan.site})
        | ({} if plan.series_uid_sha256 is None else {SERIES_HASH_KEY: plan.series_uid_sha256})
    )


def markups_document(plans: Plan | tuple[Plan, ...]) -> dict[str, Any]:
    """The 3D Slicer markups document of ``plans`` (LPS, mm): one Line per trajectory, then
    the shared landmarks (Curves, Fiducials) and the arch (a Curve whose first control point's
    description starts with the word ``arch``).

    Settings go where Slicer keeps them: ``key=value`` words in the first control point's
    description (:mod:`ctdrill.imaging.plan.settings`), so that a file loaded and saved by
    Slicer reads back as the same plan. Mask landmarks cannot be markups and are refused.
    """
    seq = (plans,) if isinstance(plans, Plan) else tuple(plans)
    plan = _shared(seq)
    markups = [
        _markup(
            "Line",
            p.name,
            np.stack([p.entry_lps, p.planned_target_lps]),
            [("entry", format_settings(_line_settings(p))), ("target", "")],
        )
        for p in seq
    ]
    for lm in plan.landmarks:
        margin = {} if lm.margin_mm is None else {"margin_mm": lm.margin_mm}
        if isinstance(lm, CanalLandmark):
            ctrl, extra = _curve_control_points(lm.points_lps)
            if len(ctrl) > MAX_CURVE_POINTS:
                raise PlanInputError(
                    f"canal {lm.name!r} has {len(ctrl)} points, more than the "
                    f"{MAX_CURVE_POINTS} a Slicer Curve may hold; save the plan as "
                    "ctdrill-plan/1 JSON or resample the canal"
                )
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
    if plan.arch_lps is not None:
        ctrl, extra = _curve_control_points(plan.arch_lps)
        desc = (f"{ARCH_ROLE} " + format_settings(extra)).strip()
        cps = [(f"arch-{i + 1}", desc if i == 0 else "") for i in range(len(ctrl))]
        markups.append(_markup("Curve", ARCH_MARKUP_NAME, ctrl, cps))
    return {"@schema": _SLICER_SCHEMA, "markups": markups}


def plan_to_dict(plan: Plan) -> dict[str, Any]:
    """The ``ctdrill-plan/1`` document of ``plan`` (LPS); mask paths are kept as given."""
    return plan_document(plan)


def plan_to_markups(plan: Plan | Sequence[Plan]) -> dict[str, Any]:
    """The 3D Slicer markups document of ``plan`` (LPS; settings in descriptions), or of
    several trajectories sharing their landmarks and arch (one Line each)."""
    return markups_document(plan if isinstance(plan, Plan) else tuple(plan))


def save_plan(plan: Plan, path: str | os.PathLike[str], *, series_uid: str | None = None) -> None:
    """Write ``plan`` atomically: Slicer markups if ``path`` ends in ``.mrk.json``, else
    ``ctdrill-plan/1`` JSON (LPS).

    ``series_uid`` (the SeriesInstanceUID the plan was made on) is recorded hashed
    (:func:`~ctdrill.imaging.plan.types.series_uid_hash`); without it the plan keeps the hash
    it has, if any.
    """
    write_plans((plan,), path, series_uid=series_uid)


def write_plans(
    plans: Sequence[Plan], path: str | os.PathLike[str], *, series_uid: str | None = None
) -> None:
    """Write every trajectory of ``plans`` into one file, atomically (written aside, then
    renamed): Slicer markups (one Line each) if ``path`` ends in ``.mrk.json``, else
    ``ctdrill-plan/1`` (one trajectory: the single form; several: ``trajectories``).

    The plans must share their landmarks and arch (a file holds one set of each) and their
    series hash; ``series_uid`` records one for all of them.

    Raises
    ------
    PlanInputError
        No plan, names not unique, landmarks/arch/series that differ between the plans.
    """
    if series_uid is not None:
        plans = [replace(p, series_uid_sha256=series_uid_hash(series_uid)) for p in plans]
    write_plan_file(tuple(plans), Path(path))
