"""Reading 3D Slicer markups (``.mrk.json``) into plan parts; the format is in
:mod:`ctdrill.imaging.plan.types`.

What is read, as 3D Slicer 5 writes it (``vtkMRMLMarkupsJsonStorageNode``):

- ``Line`` markups are trajectories (control point 1 the entry, 2 the target); ``Curve``
  markups canals (centreline: Slicer's spline, :mod:`ctdrill.imaging.plan.curve`), except
  the one marked as the dental arch by an explicit setting
  (:func:`ctdrill.imaging.plan.arch.is_arch_curve`: its first placed control point's
  description is the word ``arch``, optionally with ``curve=``; or it has no description and
  is named exactly ``dental arch``), never by a word inside a name: that Curve is the arch
  (:mod:`ctdrill.imaging.plan.arch`), the polyline Slicer draws (its spline;
  ``curve=polyline`` keeps the straight segments), at most one a file. A canal is never
  taken for the arch; an arch Curve given a canal's setting (``radius_mm``) is refused;
  ``Fiducial`` (point list) markups point landmarks, one per control point. Any other type
  (``ROI``, ``Plane``, ``Angle``, ``ClosedCurve``, ...) is skipped with a ``markups_skipped``
  warning naming it.
- Only placed control points count: ``positionStatus`` ``preview`` (being placed),
  ``undefined`` or ``missing`` are ignored (a Line needs its two points placed).
- ``coordinateSystem`` ``LPS`` (Slicer's default, and its default when absent) or ``RAS``;
  ``coordinateUnits`` ``"mm"``, ``"um"`` or the coded form ``["mm", "UCUM", "millimeter"]``.
- Settings: ``key=value`` words of the first placed control point's description
  (:mod:`ctdrill.imaging.plan.settings`), which Slicer keeps; the markup's own ``description``
  and ``attributes`` (which Slicer drops) are read too for older files; where both give a
  setting they must agree. A Fiducial's points each carry their own settings.
- A Line's implant: ``implant="NAME" implant_diameter_mm=4.1 implant_length_mm=10.0
  implant_apex_diameter_mm=2.9 implant_apex=round`` (all five, or none), and optionally its
  drilling protocol ``implant_drills="[{...}, ...]"`` (a quoted JSON list, as the implant
  object's ``drills``). A Line with an implant and no drill settings drills its protocol.
- A Line's ``min_wall_mm`` (the thinnest bone wall to keep) and ``site`` (the FDI tooth
  number, 11-48), as the plan keys.
- Names: a ``name=`` setting, else the markup's ``name``; a Line or Fiducial without either is
  named after the file's stem (one markup a file); an unnamed Curve is refused, telling the
  user to name it: no role (arch, canal, landmark) is ever taken from a file's name.
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np

from ctdrill.imaging.plan.arch import (
    ARCH_MARKUP_NAME,
    ARCH_ROLE,
    MAX_ARCH_POINTS,
    is_arch_curve,
)
from ctdrill.imaging.plan.curve import slicer_curve
from ctdrill.imaging.plan.drill_spec import _DRILL_KEYS
from ctdrill.imaging.plan.drills import drill_from, drills_field, no_drill_note, reconciled
from ctdrill.imaging.plan.implants import ImplantSpec
from ctdrill.imaging.plan.landmarks import (
    DEFAULT_CANAL_RADIUS_MM,
    CanalLandmark,
    Landmark,
    PointLandmark,
)
from ctdrill.imaging.plan.markup_fields import (
    _curve_name,
    _name,
    _number,
    _placed_points,
    _Settings,
    _settings,
    _units_mm,
)
from ctdrill.imaging.plan.read import (
    PlanParts,
    _coordinate_system,
    _Ctx,
    _make_plan,
    _stem,
    series_hash,
)
from ctdrill.imaging.plan.types import (
    DEFAULT_CALIBRATION,
    DEFAULT_FEED_MM_S,
    DEFAULT_MARGIN_MM,
    DEFAULT_MIN_WALL_MM,
    MAX_TRAJECTORIES,
    SERIES_HASH_KEY,
    DrillSpec,
    Plan,
    PlanInputError,
)
from ctdrill.safeio import loads_json
from ctdrill.warning_codes import LoadWarning

#: Markup types read; every other type is skipped with a warning.
READ_TYPES = ("Line", "Curve", "Fiducial")
#: Settings each markup type accepts in its descriptions.
#: A Line's implant settings and the implant object's key each gives.
IMPLANT_SETTINGS = {
    "implant": "name",
    "implant_diameter_mm": "diameter_mm",
    "implant_length_mm": "length_mm",
    "implant_apex_diameter_mm": "apex_diameter_mm",
    "implant_apex": "apex",
}
#: A Line's setting holding its implant's drilling protocol (a quoted JSON list).
IMPLANT_DRILLS_SETTING = "implant_drills"
LINE_KEYS = frozenset(
    {
        "name",
        *_DRILL_KEYS,
        "drills",
        "feed_mm_s",
        "calibration",
        "margin_mm",
        SERIES_HASH_KEY,
        *IMPLANT_SETTINGS,
        IMPLANT_DRILLS_SETTING,
        "min_wall_mm",
        "site",
    }
)
CURVE_KEYS = frozenset({"name", "radius_mm", "margin_mm", "curve"})
ARCH_KEYS = frozenset({"name", "curve"})
POINT_KEYS = frozenset({"name", "margin_mm"})
#: ``curve=`` values: Slicer's spline (default) or the straight segments between the points.
CURVE_SPLINE, CURVE_POLYLINE = "spline", "polyline"
#: Most control points a Curve may hold (a canal or the arch): the arch's own cap, so that
#: every polyline the writer stores as control points reads back (a hand-placed canal has
#: tens of points; its spline has 10 samples per segment).
MAX_CURVE_POINTS = MAX_ARCH_POINTS


def parse_slicer(ctx: _Ctx, doc: dict[str, Any]) -> PlanParts:
    """The trajectories (Lines) and landmarks (Curves, Fiducials) of a markups document."""
    markups = doc.get("markups")
    if not isinstance(markups, list) or not markups:
        raise ctx.fail("markups", "must be a non-empty list of Slicer markups", markups)
    only = len(markups) == 1
    n_lines = sum(isinstance(m, dict) and m.get("type") == "Line" for m in markups)
    one_line = n_lines == 1
    if n_lines > MAX_TRAJECTORIES:
        raise ctx.fail(
            "markups",
            f"hold {n_lines} Line markups (trajectories), more than the {MAX_TRAJECTORIES} a "
            "plan may hold; split the case into several plans",
        )
    lines: list[Plan] = []
    landmarks: list[Landmark] = []
    skipped: list[str] = []
    arch: tuple[np.ndarray, str] | None = None
    for m_index, mk in enumerate(markups):
        where = f"markups[{m_index}]"
        if not isinstance(mk, dict):
            raise ctx.fail(where, "must be an object", mk)
        mtype = mk.get("type")
        if mtype not in READ_TYPES:
            skipped.append(f"{where} ({mtype!s})")
            continue
        system = _coordinate_system(ctx, mk, "coordinateSystem", where)
        pts, cps = _placed_points(ctx, mk, where, system, _units_mm(ctx, mk, where))
        if mtype == "Line":
            lines.append(_line(ctx, mk, where, pts, cps, one_line, len(lines)))
        elif mtype == "Curve" and _is_arch(ctx, mk, cps, only):
            if arch is not None:
                raise ctx.fail(
                    where,
                    f"is a second arch Curve (the first is {arch[1]}); a plan has one arch",
                )
            arch = (_arch(ctx, mk, where, pts, cps), where)
        elif mtype == "Curve":
            canal = _curve(ctx, mk, where, pts, cps, only, m_index)
            if canal is not None:
                landmarks.append(canal)
        else:
            landmarks.extend(_fiducials(ctx, mk, where, pts, cps, only))
    if skipped:
        ctx.warnings.append(
            LoadWarning(
                "markups_skipped",
                f"{ctx.path.name}: skipped markups ctdrill does not use: {', '.join(skipped)} "
                "(only Line, Curve and Fiducial markups are read)",
            )
        )
    return ctx.parts(tuple(lines), tuple(landmarks), None if arch is None else arch[0])


def _is_arch(
    ctx: _Ctx, mk: dict[str, Any], cps: list[tuple[int, dict[str, Any]]], only: bool
) -> bool:
    """The Curve is the arch by its first placed point's description or, without one, by its
    markup name: :func:`is_arch_curve`. Never by the file's name (a canal saved by Slicer has
    no name, and may sit in a file called ``Dental Arch.mrk.json``)."""
    first = cps[0][1].get("description") if cps else None
    return is_arch_curve(first, _name(ctx, {}, mk, only=False))


def _arch(
    ctx: _Ctx,
    mk: dict[str, Any],
    where: str,
    pts: np.ndarray,
    cps: list[tuple[int, dict[str, Any]]],
) -> np.ndarray:
    """The arch polyline of an arch Curve: Slicer's spline, or the points (``curve=polyline``)."""
    try:
        settings = _settings(ctx, mk, cps[0] if cps else None, where, ARCH_KEYS)
    except PlanInputError as exc:
        raise PlanInputError(
            f"{exc} (this Curve is the dental arch: its description says {ARCH_ROLE!r} or it "
            f"is named {ARCH_MARKUP_NAME!r}; a canal's description gives its settings, not "
            "that word)"
        ) from None
    if len(pts) > MAX_CURVE_POINTS:
        raise ctx.fail(
            f"{where}.controlPoints",
            f"of the arch Curve hold {len(pts)} placed points, more than the "
            f"{MAX_CURVE_POINTS} accepted; resample the curve in Slicer",
        )
    kind = settings.get("curve", CURVE_SPLINE)
    if kind not in (CURVE_SPLINE, CURVE_POLYLINE):
        raise ctx.fail(
            f"{settings.origin['curve']}.curve",
            f'must be "{CURVE_SPLINE}" or "{CURVE_POLYLINE}"',
            kind,
        )
    if len(pts) < 2:
        raise ctx.fail(
            f"{where}.controlPoints",
            "of the arch Curve must hold at least 2 placed points",
            len(pts),
        )
    # Repeated control points are refused by their index (the spline would hide them).
    ctx.arch(pts.tolist(), f"{where}.controlPoints", "LPS")
    line = slicer_curve(pts) if kind == CURVE_SPLINE else pts
    return ctx.arch(line.tolist(), f"{where} (arch)", "LPS")


def _line(
    ctx: _Ctx,
    mk: dict[str, Any],
    where: str,
    pts: np.ndarray,
    cps: list[tuple[int, dict[str, Any]]],
    only: bool,
    index: int,
) -> Plan:
    if len(pts) != 2:
        raise ctx.fail(
            f"{where}.controlPoints",
            "of a Line must hold 2 placed points (entry, then target)",
            len(pts),
        )
    settings = _settings(ctx, mk, cps[0], where, LINE_KEYS)
    implant = _line_implant(ctx, settings, where)
    drills = reconciled(ctx, _line_drills(ctx, settings, where, implant), implant, where)
    feed = _number(ctx, settings, "feed_mm_s", positive=True)
    margin = _number(ctx, settings, "margin_mm")
    wall = _number(ctx, settings, "min_wall_mm")
    site = (
        ctx.site(settings["site"], f"{settings.origin['site']}: setting site")
        if "site" in settings
        else None
    )
    cal = settings.get("calibration", DEFAULT_CALIBRATION)
    if not isinstance(cal, str) or not cal.strip():
        fp = settings.origin.get("calibration", where)
        raise ctx.fail(f"{fp}.calibration", "must be a set name or a path", cal)
    name = _name(ctx, settings, mk, only) or f"{_stem(ctx.path)}-{index + 1}"
    hashed = settings.get(SERIES_HASH_KEY)
    return _make_plan(
        ctx,
        series_hash=series_hash(
            ctx, hashed, f"{settings.origin.get(SERIES_HASH_KEY, where)}.{SERIES_HASH_KEY}"
        ),
        entry=pts[0],
        target=pts[1],
        drills=drills,
        feed=DEFAULT_FEED_MM_S if feed is None else feed,
        calibration=cal,
        margin=DEFAULT_MARGIN_MM if margin is None else margin,
        name=name,
        field_path=f"{where}.controlPoints[1].position",
        implant=implant,
        min_wall=DEFAULT_MIN_WALL_MM if wall is None else wall,
        site=site,
    )


def _line_implant(ctx: _Ctx, settings: _Settings, where: str) -> ImplantSpec | None:
    """The Line's implant from its five ``implant*`` settings (all or none) and its optional
    ``implant_drills`` protocol."""
    given = [k for k in IMPLANT_SETTINGS if k in settings]
    if not given:
        if IMPLANT_DRILLS_SETTING in settings:
            raise ctx.fail(
                f"{settings.origin[IMPLANT_DRILLS_SETTING]}: setting {IMPLANT_DRILLS_SETTING}",
                "is given without an implant; give " + ", ".join(IMPLANT_SETTINGS) + " too",
            )
        return None
    fp = settings.origin[given[0]]
    missing = [k for k in IMPLANT_SETTINGS if k not in settings]
    if missing:
        raise ctx.fail(
            f"{fp}: setting {missing[0]}",
            "is missing; an implant needs all of " + ", ".join(IMPLANT_SETTINGS),
        )
    raw = {IMPLANT_SETTINGS[k]: settings[k] for k in IMPLANT_SETTINGS}
    if IMPLANT_DRILLS_SETTING in settings:
        raw["drills"] = _json_value(ctx, settings, IMPLANT_DRILLS_SETTING)
        if isinstance(raw["drills"], str):
            raise ctx.fail(
                f"{settings.origin[IMPLANT_DRILLS_SETTING]}: setting {IMPLANT_DRILLS_SETTING}",
                "must be a quoted JSON list of drills, e.g. "
                'implant_drills="[{\\"diameter_mm\\": 2.0, \\"tip_length_mm\\": 0.6}]"',
                raw["drills"],
            )
    return ctx.implant(raw, f"{fp}: implant")


def _json_value(ctx: _Ctx, settings: _Settings, key: str) -> Any:
    """A setting holding quoted JSON, parsed (a duplicate key or a huge number refused, named
    as such); text that is not JSON is returned as it is (the caller says what it must be)."""
    raw = settings[key]
    if not isinstance(raw, str):
        return raw
    where = f"{ctx.path.name}: {settings.origin[key]}: setting {key}"
    try:
        return loads_json(raw, where=where, what="value", error=PlanInputError)
    except PlanInputError as exc:
        if not isinstance(exc.__cause__, json.JSONDecodeError):
            raise
        return raw


def _line_drills(
    ctx: _Ctx, settings: _Settings, where: str, implant: ImplantSpec | None
) -> tuple[DrillSpec, ...]:
    """The Line's drills: its ``diameter_mm``... settings (one drill), or ``drills``: a quoted
    JSON list of drill objects in drilling order, as a plan file's ``drills`` (a sequence);
    neither: the implant's protocol (:func:`~ctdrill.imaging.plan.drills.drills_field`)."""
    if "drills" not in settings and not _DRILL_KEYS & set(settings) and implant is not None:
        return drills_field(ctx, {}, where, implant)
    if "drills" not in settings:
        if not _DRILL_KEYS & set(settings):
            ctx.notes.append(no_drill_note(ctx, where))
        for key in _DRILL_KEYS & set(settings):
            _number(ctx, settings, key, positive=True)  # names the description on error
        return (drill_from(ctx, {k: settings[k] for k in _DRILL_KEYS if k in settings}, where),)
    fp = settings.origin["drills"]
    given = sorted(_DRILL_KEYS & set(settings))
    if given:
        raise ctx.fail(
            f"{fp}: setting drills",
            f"and {given[0]} are both given; give the drill's settings for a single drill or "
            "drills for a sequence, not both",
        )
    raw = settings["drills"]
    value = _json_value(ctx, settings, "drills")
    if not isinstance(value, list):
        raise ctx.fail(
            f"{fp}: setting drills",
            'must be a quoted JSON list of drill objects, e.g. drills="[{\\"diameter_mm\\": '
            '2.0}, {\\"diameter_mm\\": 2.8}]"',
            raw,
        )
    return drills_field(ctx, {"drills": value}, fp)


def _curve(
    ctx: _Ctx,
    mk: dict[str, Any],
    where: str,
    pts: np.ndarray,
    cps: list[tuple[int, dict[str, Any]]],
    only: bool,
    m_index: int,
) -> CanalLandmark | None:
    if len(pts) == 0:
        ctx.warnings.append(
            LoadWarning(
                "markups_skipped", f"{ctx.path.name}: {where} (Curve) has no placed point; skipped"
            )
        )
        return None
    if len(pts) > MAX_CURVE_POINTS:
        raise ctx.fail(
            f"{where}.controlPoints",
            f"of a Curve hold {len(pts)} placed points, more than the {MAX_CURVE_POINTS} "
            "accepted (a canal needs tens); resample the curve in Slicer",
        )
    settings = _settings(ctx, mk, cps[0], where, CURVE_KEYS)
    name = _curve_name(ctx, settings, mk, where)
    radius = _number(ctx, settings, "radius_mm")
    if radius is None:
        ctx.notes.append(
            f"{ctx.path.name}: {where} ({name}) gives no radius_mm in its description; "
            f"using the default canal radius {DEFAULT_CANAL_RADIUS_MM} mm"
        )
        radius = DEFAULT_CANAL_RADIUS_MM
    kind = settings.get("curve", CURVE_SPLINE)
    if kind not in (CURVE_SPLINE, CURVE_POLYLINE):
        raise ctx.fail(
            f"{settings.origin['curve']}.curve",
            f'must be "{CURVE_SPLINE}" or "{CURVE_POLYLINE}"',
            kind,
        )
    centreline = slicer_curve(pts) if kind == CURVE_SPLINE else pts
    margin = _number(ctx, settings, "margin_mm")
    return CanalLandmark(name, centreline, radius_mm=radius, margin_mm=margin)


def _fiducials(
    ctx: _Ctx,
    mk: dict[str, Any],
    where: str,
    pts: np.ndarray,
    cps: list[tuple[int, dict[str, Any]]],
    only: bool,
) -> list[PointLandmark]:
    out = []
    base = _name(ctx, {}, mk, only) or "point"
    for i, (pt, (cp_index, cp)) in enumerate(zip(pts, cps, strict=True)):
        settings = _settings(ctx, mk, (cp_index, cp), where, POINT_KEYS)
        label = cp.get("label")
        name = settings.get("name")
        if not (isinstance(name, str) and name.strip()):
            name = label if isinstance(label, str) and label.strip() else f"{base} {i + 1}"
        margin = _number(ctx, settings, "margin_mm")
        out.append(PointLandmark(name, pt, margin_mm=margin))
    return out
