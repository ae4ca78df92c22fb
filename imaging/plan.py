"""Drill plans: ``ctdrill-plan/1`` JSON and 3D Slicer markups (``.mrk.json``), in LPS mm.

Everything is converted to LPS at this boundary (RAS: x and y negated) and validated once;
the rest of the code trusts a :class:`Plan`.

Slicer markups (``.mrk.json``): one **Line** markup is the trajectory (first control point the
entry, second the target); **Curve** markups are canals, the polyline through their control
points (Slicer draws a spline through them: place points densely); **Fiducial** markups are
point landmarks, one per control point, named by its label. Each markup may carry settings as
``key=value`` words in its ``description`` or its control points' (e.g.
``radius_mm=1.5 margin_mm=2.5`` on a curve, ``diameter_mm=2.0 tip_length_mm=0.6 blades=2
rpm=900 feed_mm_s=0.4 calibration=NAME margin_mm=2.0`` on the line); a curve without
``radius_mm`` gets :data:`~imaging.landmarks.DEFAULT_CANAL_RADIUS_MM` (1.2 mm) and the drill
defaults are those of :class:`DrillSpec`. Several Line markups make several plans
(:func:`load_plans`).
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from imaging.errors import ImagingInputError
from imaging.landmarks import (
    DEFAULT_CANAL_RADIUS_MM,
    CanalLandmark,
    Landmark,
    MaskLandmark,
    PointLandmark,
    load_mask_file,
)

PLAN_FORMAT = "ctdrill-plan/1"
#: Calibration used when a plan names none: patient CT, labelled as illustrative.
DEFAULT_CALIBRATION = "bone-illustrative"
DEFAULT_MARGIN_MM = 2.0
DEFAULT_FEED_MM_S = 0.4
_SLICER_SCHEMA = (
    "https://raw.githubusercontent.com/slicer/slicer/master/Modules/Loadable/Markups/"
    "Resources/Schema/markups-schema-v1.0.3.json#"
)
_TOP_KEYS = {
    "format",
    "coordinate_system",
    "entry_mm",
    "target_mm",
    "drill",
    "feed_mm_s",
    "calibration",
    "margin_mm",
    "landmarks",
    "name",
    "description",
    "comment",
}
_DRILL_KEYS = {"diameter_mm", "tip_length_mm", "blades", "rpm"}
_LANDMARK_KEYS = {
    "canal": {"name", "kind", "points_mm", "radius_mm", "margin_mm", "description"},
    "point": {"name", "kind", "point_mm", "points_mm", "margin_mm", "description"},
    "mask": {"name", "kind", "path", "label", "affine_lps", "margin_mm", "description"},
}


#: Largest accepted value per numeric field: far beyond any real plan, small enough that no
#: arithmetic on it overflows (a typo or a unit error is refused, not computed with).
_MAXIMA = {
    "diameter_mm": 50.0,
    "tip_length_mm": 50.0,
    "rpm": 1e6,
    "feed_mm_s": 1000.0,
    "margin_mm": 1000.0,
    "radius_mm": 1000.0,
}
#: Largest accepted coordinate magnitude, mm.
_MAX_COORD_MM = 1e5
_MAX_BLADES = 100


class PlanInputError(ImagingInputError):
    """A plan file that cannot be used; the message names the file and the field path."""


@dataclass(frozen=True)
class DrillSpec:
    """The drill: diameter and tip (cone) length in mm, number of blades, speed in rpm."""

    diameter_mm: float = 2.0
    tip_length_mm: float = 0.6
    blades: int = 2
    rpm: float = 900.0

    @property
    def radius_mm(self) -> float:
        """Half the diameter, mm."""
        return self.diameter_mm / 2.0


@dataclass(frozen=True, eq=False)
class Plan:
    """One planned osteotomy, LPS mm.

    Attributes
    ----------
    entry_lps, target_lps : (3,) read-only float64; depth 0 is the entry point.
    drill : the drill.
    feed_mm_s : feed rate for exports and rehearsal, mm/s.
    calibration : calibration set name (``assets/calibration/``) or path.
    margin_mm : safety margin to every landmark without its own ``margin_mm``.
    landmarks : the structures to protect.
    name : a short label (the file stem, or the Slicer line's name).
    source : the file it was read from ("" if built in code).
    notes : defaults the reader filled in that the user should know (e.g. a canal radius).
    """

    entry_lps: np.ndarray
    target_lps: np.ndarray
    drill: DrillSpec = field(default_factory=DrillSpec)
    feed_mm_s: float = DEFAULT_FEED_MM_S
    calibration: str = DEFAULT_CALIBRATION
    margin_mm: float = DEFAULT_MARGIN_MM
    landmarks: tuple[Landmark, ...] = ()
    name: str = "plan"
    source: str = ""
    notes: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        for attr in ("entry_lps", "target_lps"):
            arr = np.array(getattr(self, attr), dtype=np.float64).reshape(3)
            arr.flags.writeable = False
            object.__setattr__(self, attr, arr)
        object.__setattr__(self, "landmarks", tuple(self.landmarks))

    @property
    def planned_depth_mm(self) -> float:
        """``|target - entry|``, mm."""
        return float(np.linalg.norm(self.target_lps - self.entry_lps))

    @property
    def direction(self) -> np.ndarray:
        """(3,) unit vector from entry to target."""
        out: np.ndarray = (self.target_lps - self.entry_lps) / self.planned_depth_mm
        return out

    def landmark_margin_mm(self, landmark: Landmark) -> float:
        """The margin that applies to ``landmark`` (its own, else the plan's), mm."""
        return self.margin_mm if landmark.margin_mm is None else float(landmark.margin_mm)

    def point_at_depth_lps(self, depth_mm: float) -> np.ndarray:
        """(3,) LPS point on the axis at ``depth_mm`` from the entry."""
        out: np.ndarray = self.entry_lps + depth_mm * self.direction
        return out


# --------------------------------------------------------------------------- validation


def _is_number(value: object) -> bool:
    """A finite JSON number (not a bool; an integer beyond the float range is not finite)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return False
    try:
        return math.isfinite(float(value))
    except OverflowError:
        return False


class _Ctx:
    """Where we are in a file, for error messages."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.notes: list[str] = []

    def fail(self, field_path: str, what: str, got: object = ...) -> PlanInputError:
        tail = "" if got is ... else f", got {got!r}"
        return PlanInputError(f"{self.path.name}: {field_path} {what}{tail}")

    def number(
        self,
        obj: dict[str, Any],
        key: str,
        where: str,
        *,
        default: float | None = None,
        positive: bool = False,
        nonneg: bool = False,
    ) -> float:
        fp = f"{where}.{key}" if where else key
        if key not in obj:
            if default is None:
                raise self.fail(fp, "is missing; add it")
            return default
        val = obj[key]
        ok = _is_number(val)
        if ok and positive and not val > 0:
            ok = False
        if ok and nonneg and not val >= 0:
            ok = False
        if not ok:
            kind = "a positive number" if positive else "a number >= 0" if nonneg else "a number"
            raise self.fail(fp, f"must be {kind}", val)
        top = _MAXIMA.get(key)
        if top is not None and not val <= top:
            raise self.fail(fp, f"must be at most {top:g} (check the units)", val)
        return float(val)

    def point(self, val: object, fp: str) -> np.ndarray:
        if (
            not isinstance(val, list | tuple)
            or len(val) != 3
            or not all(_is_number(v) and abs(v) <= _MAX_COORD_MM for v in val)
        ):
            raise self.fail(
                fp,
                f"must be a list of 3 finite numbers [x, y, z] in mm (|v| <= {_MAX_COORD_MM:g})",
                val,
            )
        return np.asarray(val, dtype=np.float64)

    def string(self, obj: dict[str, Any], key: str, where: str, *, default: str | None) -> str:
        fp = f"{where}.{key}" if where else key
        if key not in obj:
            if default is None:
                raise self.fail(fp, "is missing; add it")
            return default
        val = obj[key]
        if not isinstance(val, str) or not val.strip():
            raise self.fail(fp, "must be a non-empty string", val)
        return val

    def keys(self, obj: dict[str, Any], allowed: set[str], where: str) -> None:
        extra = sorted(set(obj) - allowed)
        if extra:
            fp = f"{where}.{extra[0]}" if where else extra[0]
            raise self.fail(fp, f"is not a known field (known: {', '.join(sorted(allowed))})")


def _read_json(path: Path) -> Any:
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError as exc:
        raise PlanInputError(f"{path}: plan file not found; check the path") from exc
    except IsADirectoryError as exc:
        raise PlanInputError(f"{path}: is a folder, expected a plan file") from exc
    except (OSError, UnicodeDecodeError) as exc:
        raise PlanInputError(f"{path}: cannot read the plan as UTF-8 text ({exc})") from exc
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise PlanInputError(
            f"{path.name}: not valid JSON (line {exc.lineno}, column {exc.colno}: {exc.msg})"
        ) from exc


def _to_lps(points: np.ndarray, system: str) -> np.ndarray:
    if system == "LPS":
        return points
    out = np.array(points, dtype=np.float64, copy=True)
    out[..., 0] *= -1.0
    out[..., 1] *= -1.0
    return out


def _coordinate_system(ctx: _Ctx, obj: dict[str, Any], key: str, where: str) -> str:
    fp = f"{where}.{key}" if where else key
    system = obj.get(key, "LPS")
    if not isinstance(system, str) or system.upper() not in ("LPS", "RAS"):
        raise ctx.fail(fp, 'must be "LPS" or "RAS"', system)
    return system.upper()


def _check_margin(ctx: _Ctx, obj: dict[str, Any], where: str) -> float | None:
    if "margin_mm" not in obj:
        return None
    return ctx.number(obj, "margin_mm", where, nonneg=True)


def _parse_landmark(ctx: _Ctx, raw: object, index: int, system: str, base_dir: Path) -> Landmark:
    where = f"landmarks[{index}]"
    if not isinstance(raw, dict):
        raise ctx.fail(where, "must be an object", raw)
    kind = raw.get("kind")
    if not isinstance(kind, str) or kind not in _LANDMARK_KEYS:
        raise ctx.fail(f"{where}.kind", 'must be "canal", "point" or "mask"', kind)
    ctx.keys(raw, _LANDMARK_KEYS[kind], where)
    name = ctx.string(raw, "name", where, default=f"{kind} {index + 1}")
    margin = _check_margin(ctx, raw, where)
    if kind == "canal":
        pts_raw = raw.get("points_mm")
        if not isinstance(pts_raw, list) or len(pts_raw) == 0:
            raise ctx.fail(
                f"{where}.points_mm", "must be a non-empty list of [x, y, z] points", pts_raw
            )
        pts = np.stack([ctx.point(p, f"{where}.points_mm[{i}]") for i, p in enumerate(pts_raw)])
        radius = ctx.number(raw, "radius_mm", where, default=DEFAULT_CANAL_RADIUS_MM, nonneg=True)
        if "radius_mm" not in raw:
            ctx.notes.append(
                f"{ctx.path.name}: {where} ({name}) has no radius_mm; using the default "
                f"{DEFAULT_CANAL_RADIUS_MM} mm"
            )
        return CanalLandmark(name, _to_lps(pts, system), radius_mm=radius, margin_mm=margin)
    if kind == "point":
        if "point_mm" in raw:
            pt = ctx.point(raw["point_mm"], f"{where}.point_mm")
        else:
            pts_raw = raw.get("points_mm")
            if not isinstance(pts_raw, list) or len(pts_raw) != 1:
                raise ctx.fail(f"{where}.point_mm", "is missing; give [x, y, z] in mm")
            pt = ctx.point(pts_raw[0], f"{where}.points_mm[0]")
        return PointLandmark(name, _to_lps(pt, system), margin_mm=margin)
    rel = ctx.string(raw, "path", where, default=None)
    label = raw.get("label")
    if label is not None and (
        not isinstance(label, int) or isinstance(label, bool) or not -(2**63) <= label < 2**63
    ):
        raise ctx.fail(f"{where}.label", "must be an integer label value", label)
    affine = None
    if "affine_lps" in raw:
        aff = np.asarray(raw["affine_lps"], dtype=object)
        try:
            affine = np.asarray(aff, dtype=np.float64)
        except (TypeError, ValueError, OverflowError):
            affine = None
        if affine is None or affine.shape != (4, 4) or not np.all(np.isfinite(affine)):
            raise ctx.fail(f"{where}.affine_lps", "must be a 4x4 matrix of finite numbers")
    mask_path = Path(rel) if Path(rel).is_absolute() else base_dir / rel
    mask = load_mask_file(mask_path, label=label)
    return MaskLandmark(name, mask, affine_lps=affine, margin_mm=margin, source=rel)


def _parse_ctdrill(ctx: _Ctx, doc: dict[str, Any]) -> Plan:
    fmt = doc.get("format")
    if fmt != PLAN_FORMAT:
        raise ctx.fail("format", f'must be "{PLAN_FORMAT}"', fmt)
    ctx.keys(doc, _TOP_KEYS, "")
    system = _coordinate_system(ctx, doc, "coordinate_system", "")
    for key in ("entry_mm", "target_mm"):
        if key not in doc:
            raise ctx.fail(key, "is missing; add [x, y, z] in mm")
    entry = _to_lps(ctx.point(doc["entry_mm"], "entry_mm"), system)
    target = _to_lps(ctx.point(doc["target_mm"], "target_mm"), system)
    drill_raw = doc.get("drill", {})
    if not isinstance(drill_raw, dict):
        raise ctx.fail("drill", "must be an object", drill_raw)
    ctx.keys(drill_raw, _DRILL_KEYS, "drill")
    drill = _drill_from(ctx, drill_raw, "drill")
    feed = ctx.number(doc, "feed_mm_s", "", default=DEFAULT_FEED_MM_S, positive=True)
    calibration = ctx.string(doc, "calibration", "", default=DEFAULT_CALIBRATION)
    margin = ctx.number(doc, "margin_mm", "", default=DEFAULT_MARGIN_MM, nonneg=True)
    lms_raw = doc.get("landmarks", [])
    if not isinstance(lms_raw, list):
        raise ctx.fail("landmarks", "must be a list", lms_raw)
    base = ctx.path.parent
    landmarks = tuple(_parse_landmark(ctx, r, i, system, base) for i, r in enumerate(lms_raw))
    name = doc.get("name") if isinstance(doc.get("name"), str) else None
    return _make_plan(
        ctx,
        entry=entry,
        target=target,
        drill=drill,
        feed=feed,
        calibration=calibration,
        margin=margin,
        landmarks=landmarks,
        name=name or _stem(ctx.path),
        field_path="target_mm",
    )


def _drill_from(ctx: _Ctx, raw: dict[str, Any], where: str) -> DrillSpec:
    d = DrillSpec()
    diameter = ctx.number(raw, "diameter_mm", where, default=d.diameter_mm, positive=True)
    tip = ctx.number(raw, "tip_length_mm", where, default=d.tip_length_mm, positive=True)
    blades_raw = raw.get("blades", d.blades)
    if not _is_number(blades_raw) or blades_raw != int(blades_raw) or blades_raw < 1:
        raise ctx.fail(f"{where}.blades", "must be a positive whole number", blades_raw)
    if blades_raw > _MAX_BLADES:
        raise ctx.fail(f"{where}.blades", f"must be at most {_MAX_BLADES}", blades_raw)
    rpm = ctx.number(raw, "rpm", where, default=d.rpm, positive=True)
    return DrillSpec(diameter_mm=diameter, tip_length_mm=tip, blades=int(blades_raw), rpm=rpm)


def _make_plan(
    ctx: _Ctx,
    *,
    entry: np.ndarray,
    target: np.ndarray,
    drill: DrillSpec,
    feed: float,
    calibration: str,
    margin: float,
    landmarks: tuple[Landmark, ...],
    name: str,
    field_path: str,
) -> Plan:
    if not np.linalg.norm(target - entry) > 1e-6:
        raise ctx.fail(field_path, "must differ from the entry point (the planned depth is 0)")
    return Plan(
        entry_lps=entry,
        target_lps=target,
        drill=drill,
        feed_mm_s=feed,
        calibration=calibration,
        margin_mm=margin,
        landmarks=landmarks,
        name=name,
        source=str(ctx.path),
        notes=tuple(ctx.notes),
    )


def _stem(path: Path) -> str:
    name = path.name
    for suffix in (".mrk.json", ".json"):
        if name.lower().endswith(suffix):
            return name[: -len(suffix)]
    return path.stem


# --------------------------------------------------------------------------- Slicer markups


def _settings(ctx: _Ctx, markup: dict[str, Any], where: str) -> dict[str, Any]:
    """Settings of a markup: ``key=value`` words (numbers parsed) of its control points'
    descriptions, then of its own ``description``, then its ``attributes`` (later wins)."""
    out: dict[str, Any] = {}
    texts = [
        cp.get("description") for cp in markup.get("controlPoints") or [] if isinstance(cp, dict)
    ]
    texts.append(markup.get("description"))
    for desc in texts:
        if not isinstance(desc, str):
            continue
        for word in desc.replace(",", " ").replace(";", " ").split():
            if "=" not in word:
                continue
            key, _, value = word.partition("=")
            try:
                out[key.strip()] = float(value) if key.strip() != "calibration" else value
            except ValueError:
                out[key.strip()] = value
    attrs = markup.get("attributes")
    if isinstance(attrs, dict):
        out.update(attrs)
    return out


def _control_points(ctx: _Ctx, markup: dict[str, Any], where: str, system: str) -> np.ndarray:
    cps = markup.get("controlPoints")
    if not isinstance(cps, list):
        raise ctx.fail(f"{where}.controlPoints", "must be a list", cps)
    pts = []
    for i, cp in enumerate(cps):
        if not isinstance(cp, dict) or "position" not in cp:
            raise ctx.fail(f"{where}.controlPoints[{i}].position", "is missing")
        pts.append(ctx.point(cp["position"], f"{where}.controlPoints[{i}].position"))
    return _to_lps(np.asarray(pts, dtype=np.float64).reshape(-1, 3), system)


def _parse_slicer(ctx: _Ctx, doc: dict[str, Any]) -> tuple[Plan, ...]:
    markups = doc.get("markups")
    if not isinstance(markups, list) or not markups:
        raise ctx.fail("markups", "must be a non-empty list of Slicer markups", markups)
    lines: list[tuple[str, np.ndarray, dict[str, Any], str]] = []
    landmarks: list[Landmark] = []
    for m_index, mk in enumerate(markups):
        where = f"markups[{m_index}]"
        if not isinstance(mk, dict):
            raise ctx.fail(where, "must be an object", mk)
        mtype = mk.get("type")
        system = _coordinate_system(ctx, mk, "coordinateSystem", where)
        units = mk.get("coordinateUnits", "mm")
        if units != "mm":
            raise ctx.fail(f"{where}.coordinateUnits", 'must be "mm"', units)
        pts = _control_points(ctx, mk, where, system)
        settings = _settings(ctx, mk, where)
        label = mk.get("name") if isinstance(mk.get("name"), str) else None
        margin = _setting_number(ctx, settings, "margin_mm", where, nonneg=True)
        if mtype == "Line":
            if len(pts) != 2:
                raise ctx.fail(
                    f"{where}.controlPoints",
                    "of a Line must hold 2 points (entry, then target)",
                    len(pts),
                )
            lines.append((label or "", pts, settings, where))
        elif mtype == "Curve":
            if len(pts) == 0:
                raise ctx.fail(f"{where}.controlPoints", "of a Curve must hold at least 1 point")
            radius = _setting_number(ctx, settings, "radius_mm", where, nonneg=True)
            landmarks.append(
                CanalLandmark(
                    label or f"canal {m_index + 1}",
                    pts,
                    radius_mm=_default_radius(ctx, radius, where, label),
                    margin_mm=margin,
                )
            )
        elif mtype == "Fiducial":
            cps = mk["controlPoints"]
            for i, pt in enumerate(pts):
                cp_label = cps[i].get("label")
                name = cp_label if isinstance(cp_label, str) and cp_label else None
                landmarks.append(
                    PointLandmark(name or f"{label or 'point'} {i + 1}", pt, margin_mm=margin)
                )
        else:
            raise ctx.fail(f"{where}.type", 'must be "Line", "Curve" or "Fiducial"', mtype)
    if not lines:
        raise ctx.fail("markups", "hold no Line markup; add one Line (entry, then target)")
    plans = []
    for index, (label, pts, settings, where) in enumerate(lines):
        drill_raw = {k: settings[k] for k in _DRILL_KEYS if k in settings}
        drill = _drill_from(ctx, drill_raw, f"{where}.description")
        feed = _setting_number(ctx, settings, "feed_mm_s", where, positive=True)
        margin = _setting_number(ctx, settings, "margin_mm", where, nonneg=True)
        cal = settings.get("calibration", DEFAULT_CALIBRATION)
        plans.append(
            _make_plan(
                ctx,
                entry=pts[0],
                target=pts[1],
                drill=drill,
                feed=DEFAULT_FEED_MM_S if feed is None else feed,
                calibration=str(cal),
                margin=DEFAULT_MARGIN_MM if margin is None else margin,
                landmarks=tuple(landmarks),
                name=label or (_stem(ctx.path) + (f"-{index + 1}" if len(lines) > 1 else "")),
                field_path=f"{where}.controlPoints[1].position",
            )
        )
    return tuple(plans)


def _default_radius(ctx: _Ctx, radius: float | None, where: str, label: str | None) -> float:
    if radius is not None:
        return radius
    ctx.notes.append(
        f"{ctx.path.name}: {where} ({label or 'curve'}) gives no radius_mm in its description; "
        f"using the default canal radius {DEFAULT_CANAL_RADIUS_MM} mm"
    )
    return DEFAULT_CANAL_RADIUS_MM


def _setting_number(
    ctx: _Ctx,
    settings: dict[str, Any],
    key: str,
    where: str,
    *,
    positive: bool = False,
    nonneg: bool = False,
) -> float | None:
    if key not in settings:
        return None
    return ctx.number(
        settings, key, f"{where}.description", positive=positive, nonneg=nonneg, default=None
    )


# --------------------------------------------------------------------------- public API


def load_plans(path: str | os.PathLike[str]) -> tuple[Plan, ...]:
    """Read every trajectory of a plan file, converted to LPS and validated.

    A ``ctdrill-plan/1`` file holds one trajectory; a Slicer ``.mrk.json`` holds one per
    Line markup (all sharing the file's landmarks).

    Raises
    ------
    PlanInputError
        Naming the file and the field path (``plan.json: drill.diameter_mm must be ...``).
    """
    p = Path(path)
    ctx = _Ctx(p)
    doc = _read_json(p)
    if not isinstance(doc, dict):
        raise ctx.fail("(top level)", "must be a JSON object", type(doc).__name__)
    if "markups" in doc and "format" not in doc:
        return _parse_slicer(ctx, doc)
    if "format" not in doc:
        raise ctx.fail(
            "format",
            f'is missing; a plan starts with "format": "{PLAN_FORMAT}" '
            "(or is a 3D Slicer .mrk.json with markups)",
        )
    return (_parse_ctdrill(ctx, doc),)


def load_plan(path: str | os.PathLike[str]) -> Plan:
    """Read a plan file holding exactly one trajectory (see :func:`load_plans`)."""
    plans = load_plans(path)
    if len(plans) != 1:
        raise PlanInputError(
            f"{Path(path).name}: holds {len(plans)} trajectories (Line markups); "
            "keep one or load them with load_plans()"
        )
    return plans[0]


def plan_to_dict(plan: Plan) -> dict[str, Any]:
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


def plan_to_markups(plan: Plan) -> dict[str, Any]:
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


def save_plan(plan: Plan, path: str | os.PathLike[str]) -> None:
    """Write ``plan`` atomically: Slicer markups if ``path`` ends in ``.mrk.json``, else
    ``ctdrill-plan/1`` JSON (LPS)."""
    p = Path(path)
    doc = plan_to_markups(plan) if p.name.lower().endswith(".mrk.json") else plan_to_dict(plan)
    text = json.dumps(doc, indent=2) + "\n"
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=p.parent or ".")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, p)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
