"""Reading 3D Slicer markups (``.mrk.json``) into plan parts; the format is in
:mod:`ctdrill.imaging.plan.types`.

What is read, as 3D Slicer 5 writes it (``vtkMRMLMarkupsJsonStorageNode``):

- ``Line`` markups are trajectories (control point 1 the entry, 2 the target); ``Curve``
  markups canals (centreline: Slicer's spline, :mod:`ctdrill.imaging.plan.curve`);
  ``Fiducial`` (point list) markups point landmarks, one per control point. Any other type
  (``ROI``, ``Plane``, ``Angle``, ``ClosedCurve``, ...) is skipped with a ``markups_skipped``
  warning naming it.
- Only placed control points count: ``positionStatus`` ``preview`` (being placed),
  ``undefined`` or ``missing`` are ignored (a Line needs its two points placed).
- ``coordinateSystem`` ``LPS`` (Slicer's default, and its default when absent) or ``RAS``;
  ``coordinateUnits`` ``"mm"``, ``"um"`` or the coded form ``["mm", "UCUM", "millimeter"]``.
- Settings: ``key=value`` words of the first placed control point's description
  (:mod:`ctdrill.imaging.plan.settings`), which Slicer keeps; the markup's own ``description``
  and ``attributes`` (which Slicer drops) are read too for older files, the control point
  winning. A Fiducial's points each carry their own settings.
- Names: a ``name=`` setting, else the markup's ``name``, else (Slicer writes no name; it
  names the node after the file) the file's stem when the file holds one markup.
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np

from ctdrill.imaging.plan.curve import slicer_curve
from ctdrill.imaging.plan.drills import drill_from, drills_field, no_drill_note
from ctdrill.imaging.plan.landmarks import (
    DEFAULT_CANAL_RADIUS_MM,
    CanalLandmark,
    Landmark,
    PointLandmark,
)
from ctdrill.imaging.plan.read import (
    PlanParts,
    _coordinate_system,
    _Ctx,
    _make_plan,
    _stem,
    _to_lps,
    series_hash,
)
from ctdrill.imaging.plan.settings import SettingsSyntaxError, parse_settings
from ctdrill.imaging.plan.types import (
    _DRILL_KEYS,
    DEFAULT_CALIBRATION,
    DEFAULT_FEED_MM_S,
    DEFAULT_MARGIN_MM,
    SERIES_HASH_KEY,
    DrillSpec,
    Plan,
)

#: Markup types read; every other type is skipped with a warning.
READ_TYPES = ("Line", "Curve", "Fiducial")
#: Settings each markup type accepts in its descriptions.
LINE_KEYS = frozenset(
    {"name", *_DRILL_KEYS, "drills", "feed_mm_s", "calibration", "margin_mm", SERIES_HASH_KEY}
)
CURVE_KEYS = frozenset({"name", "radius_mm", "margin_mm", "curve"})
POINT_KEYS = frozenset({"name", "margin_mm"})
#: ``curve=`` values: Slicer's spline (default) or the straight segments between the points.
CURVE_SPLINE, CURVE_POLYLINE = "spline", "polyline"
#: ``positionStatus`` values of a placed point (absent means placed, as in Slicer).
_PLACED = "defined"
_UNPLACED = ("preview", "undefined", "missing")
#: Most control points a Curve may hold: its centreline has 10 samples per segment, and
#: 20 000 points (200 000 samples) is far beyond a hand-placed canal (tens of points).
MAX_CURVE_POINTS = 20_000
#: Length units accepted in ``coordinateUnits`` and their size in mm.
_UNITS_MM = {"mm": 1.0, "um": 1e-3}


def _units_mm(ctx: _Ctx, markup: dict[str, Any], where: str) -> float:
    """Millimetres per coordinate unit: ``"mm"``/``"um"``, or coded ``[code, "UCUM", meaning]``."""
    units = markup.get("coordinateUnits", "mm")
    code = units
    if isinstance(units, list):
        if (
            len(units) != 3
            or not all(isinstance(u, str) for u in units)
            or units[1].upper() != "UCUM"
        ):
            raise ctx.fail(
                f"{where}.coordinateUnits",
                'must be "mm" or a UCUM code such as ["mm", "UCUM", "millimeter"]',
                units,
            )
        code = units[0]
    if not isinstance(code, str) or code not in _UNITS_MM:
        raise ctx.fail(f"{where}.coordinateUnits", 'must be "mm" or "um"', units)
    return _UNITS_MM[code]


def _placed_points(
    ctx: _Ctx, markup: dict[str, Any], where: str, system: str, scale: float
) -> tuple[np.ndarray, list[tuple[int, dict[str, Any]]]]:
    """LPS mm positions of the placed control points, and those (index, control point)."""
    cps = markup.get("controlPoints", [])
    if not isinstance(cps, list):
        raise ctx.fail(f"{where}.controlPoints", "must be a list", cps)
    pts, kept = [], []
    for i, cp in enumerate(cps):
        fp = f"{where}.controlPoints[{i}]"
        if not isinstance(cp, dict):
            raise ctx.fail(fp, "must be an object", cp)
        status = cp.get("positionStatus", _PLACED)
        if status in _UNPLACED:
            continue
        if status != _PLACED:
            raise ctx.fail(f"{fp}.positionStatus", 'must be "defined", "preview" or "undefined"')
        if "position" not in cp:
            raise ctx.fail(f"{fp}.position", "is missing")
        pts.append(ctx.point(cp["position"], f"{fp}.position") * scale)
        kept.append((i, cp))
    arr = _to_lps(np.asarray(pts, dtype=np.float64).reshape(-1, 3), system)
    return arr, kept


class _Settings(dict[str, Any]):
    """Settings, and for each the field path of the description it came from."""

    def __init__(self) -> None:
        super().__init__()
        self.origin: dict[str, str] = {}


def _settings(
    ctx: _Ctx,
    markup: dict[str, Any],
    cp: tuple[int, dict[str, Any]] | None,
    where: str,
    allowed: frozenset[str],
) -> _Settings:
    """Settings of the markup's description and attributes, then of control point ``cp``
    (its index in ``controlPoints`` and itself), the control point winning."""
    out = _Settings()
    sources: list[tuple[object, str]] = [(markup.get("description"), f"{where}.description")]
    attrs = markup.get("attributes")
    if cp is not None:
        sources.append((cp[1].get("description"), f"{where}.controlPoints[{cp[0]}].description"))
    for text, fp in sources:
        if text is None:
            continue
        if not isinstance(text, str):
            raise ctx.fail(fp, "must be a string", text)
        try:
            found = parse_settings(text)
        except SettingsSyntaxError as exc:
            raise ctx.fail(fp, f"holds a malformed setting: {exc}") from exc
        out.update(found)
        out.origin.update(dict.fromkeys(found, fp))
    if isinstance(attrs, dict):
        for key, value in attrs.items():
            if key not in out:
                out[key] = value
                out.origin[key] = f"{where}.attributes"
    unknown = sorted(set(out) - allowed)
    if unknown:
        raise ctx.fail(
            f"{out.origin[unknown[0]]}: setting {unknown[0]}",
            f"is not a setting of this markup (known: {', '.join(sorted(allowed))})",
        )
    return out


def _name(ctx: _Ctx, settings: dict[str, Any], markup: dict[str, Any], only: bool) -> str | None:
    name = settings.get("name")
    if isinstance(name, str) and name.strip():
        return name
    label = markup.get("name")
    if isinstance(label, str) and label.strip():
        return label
    return _stem(ctx.path) if only else None


def parse_slicer(ctx: _Ctx, doc: dict[str, Any]) -> PlanParts:
    """The trajectories (Lines) and landmarks (Curves, Fiducials) of a markups document."""
    markups = doc.get("markups")
    if not isinstance(markups, list) or not markups:
        raise ctx.fail("markups", "must be a non-empty list of Slicer markups", markups)
    only = len(markups) == 1
    one_line = sum(isinstance(m, dict) and m.get("type") == "Line" for m in markups) == 1
    lines: list[Plan] = []
    landmarks: list[Landmark] = []
    skipped: list[str] = []
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
        elif mtype == "Curve":
            canal = _curve(ctx, mk, where, pts, cps, only, m_index)
            if canal is not None:
                landmarks.append(canal)
        else:
            landmarks.extend(_fiducials(ctx, mk, where, pts, cps, only))
    if skipped:
        ctx.warnings.append(
            (
                "markups_skipped",
                f"{ctx.path.name}: skipped markups ctdrill does not use: {', '.join(skipped)} "
                "(only Line, Curve and Fiducial markups are read)",
            )
        )
    return ctx.parts(tuple(lines), tuple(landmarks))


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
    drills = _line_drills(ctx, settings, where)
    feed = _number(ctx, settings, "feed_mm_s", positive=True)
    margin = _number(ctx, settings, "margin_mm")
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
    )


def _line_drills(ctx: _Ctx, settings: _Settings, where: str) -> tuple[DrillSpec, ...]:
    """The Line's drills: its ``diameter_mm``... settings (one drill), or ``drills``: a quoted
    JSON list of drill objects in drilling order, as a plan file's ``drills`` (a sequence)."""
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
    try:
        value = json.loads(raw) if isinstance(raw, str) else raw
    except json.JSONDecodeError:
        value = raw
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
            ("markups_skipped", f"{ctx.path.name}: {where} (Curve) has no placed point; skipped")
        )
        return None
    if len(pts) > MAX_CURVE_POINTS:
        raise ctx.fail(
            f"{where}.controlPoints",
            f"of a Curve hold {len(pts)} placed points, more than the {MAX_CURVE_POINTS} "
            "accepted (a canal needs tens); resample the curve in Slicer",
        )
    settings = _settings(ctx, mk, cps[0], where, CURVE_KEYS)
    name = _name(ctx, settings, mk, only) or f"canal {m_index + 1}"
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


def _number(ctx: _Ctx, settings: _Settings, key: str, *, positive: bool = False) -> float | None:
    if key not in settings:
        return None
    where = settings.origin[key]
    return ctx.number(settings, key, where, positive=positive, nonneg=not positive)
