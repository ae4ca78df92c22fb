"""Reading plan documents: ``ctdrill-plan/1`` JSON and 3D Slicer markups, validated, to LPS.

The formats are described in :mod:`ctdrill.imaging.plan.types`; this module holds the parsers behind
:func:`ctdrill.imaging.plan.types.load_plans`.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ctdrill.imaging.plan.landmarks import (
    DEFAULT_CANAL_RADIUS_MM,
    CanalLandmark,
    Landmark,
    PointLandmark,
)
from ctdrill.imaging.plan.types import (
    _LANDMARK_KEYS,
    _MAX_COORD_MM,
    _MAXIMA,
    _TOP_KEYS,
    DEFAULT_CALIBRATION,
    DEFAULT_FEED_MM_S,
    DEFAULT_MARGIN_MM,
    PLAN_FORMAT,
    SERIES_HASH_KEY,
    DrillSpec,
    Plan,
    PlanInputError,
    is_series_hash,
)
from ctdrill.safeio import load_json

# --------------------------------------------------------------------------- validation


@dataclass(frozen=True, eq=False)
class PlanParts:
    """What one plan file holds, before files are merged into plans.

    Attributes
    ----------
    source : the file.
    trajectories : its trajectories, as plans without landmarks (possibly none).
    landmarks : its landmarks (possibly none).
    notes : defaults the reader filled in (``plan_default`` warnings).
    warnings : ``(code, message)`` pairs for the summary (e.g. ``markups_skipped``).
    """

    source: Path
    trajectories: tuple[Plan, ...] = ()
    landmarks: tuple[Landmark, ...] = ()
    notes: tuple[str, ...] = ()
    warnings: tuple[tuple[str, str], ...] = field(default_factory=tuple)


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
        self.warnings: list[tuple[str, str]] = []

    def parts(self, trajectories: tuple[Plan, ...], landmarks: tuple[Landmark, ...]) -> PlanParts:
        """The file's parts with the notes and warnings gathered while reading it."""
        return PlanParts(
            self.path, trajectories, landmarks, tuple(self.notes), tuple(self.warnings)
        )

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
    return load_json(path, what="plan file", error=PlanInputError)


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
    segment = raw.get("segment")
    if segment is not None and (not isinstance(segment, str) or not segment.strip()):
        raise ctx.fail(f"{where}.segment", "must be a segment's name", segment)
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
    from ctdrill.imaging.plan.segmentation import mask_landmark

    return mask_landmark(
        mask_path,
        name=name,
        label=label,
        segment=segment,
        affine_lps=affine,
        margin_mm=margin,
        source=str(mask_path),
    )


def _parse_ctdrill(ctx: _Ctx, doc: dict[str, Any]) -> PlanParts:
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
    from ctdrill.imaging.plan.drills import drills_field  # it reads with this module's _Ctx

    drills = drills_field(ctx, doc, "")
    feed = ctx.number(doc, "feed_mm_s", "", default=DEFAULT_FEED_MM_S, positive=True)
    calibration = ctx.string(doc, "calibration", "", default=DEFAULT_CALIBRATION)
    margin = ctx.number(doc, "margin_mm", "", default=DEFAULT_MARGIN_MM, nonneg=True)
    lms_raw = doc.get("landmarks", [])
    if not isinstance(lms_raw, list):
        raise ctx.fail("landmarks", "must be a list", lms_raw)
    base = ctx.path.parent
    landmarks = tuple(_parse_landmark(ctx, r, i, system, base) for i, r in enumerate(lms_raw))
    name = doc.get("name") if isinstance(doc.get("name"), str) else None
    plan = _make_plan(
        ctx,
        series_hash=series_hash(ctx, doc.get(SERIES_HASH_KEY), SERIES_HASH_KEY),
        entry=entry,
        target=target,
        drills=drills,
        feed=feed,
        calibration=calibration,
        margin=margin,
        name=name or _stem(ctx.path),
        field_path="target_mm",
    )
    return ctx.parts((plan,), landmarks)


def series_hash(ctx: _Ctx, value: object, field_path: str) -> str | None:
    """The recorded series hash (``series_uid_sha256``), or None when absent."""
    if value is None:
        return None
    if not is_series_hash(value):
        raise ctx.fail(
            field_path,
            "must be the 64 lower-case hex digits ctdrill writes (a hashed SeriesInstanceUID); "
            "delete it to use the plan on any series",
            value,
        )
    return str(value)


def _make_plan(
    ctx: _Ctx,
    *,
    series_hash: str | None = None,
    entry: np.ndarray,
    target: np.ndarray,
    drills: tuple[DrillSpec, ...],
    feed: float,
    calibration: str,
    margin: float,
    name: str,
    field_path: str,
) -> Plan:
    """One trajectory of the file (its landmarks are joined by :func:`merge_parts`)."""
    if not np.linalg.norm(target - entry) > 1e-6:
        raise ctx.fail(field_path, "must differ from the entry point (the planned depth is 0)")
    return Plan(
        entry_lps=entry,
        target_lps=target,
        drill=drills[-1],
        earlier_drills=drills[:-1],
        feed_mm_s=feed,
        calibration=calibration,
        margin_mm=margin,
        name=name,
        source=str(ctx.path),
        series_uid_sha256=series_hash,
    )


def _stem(path: Path) -> str:
    name = path.name
    for suffix in (".mrk.json", ".json"):
        if name.lower().endswith(suffix):
            return name[: -len(suffix)]
    return path.stem


def read_parts(path: str | os.PathLike[str]) -> PlanParts:
    """Read one plan file's trajectories and landmarks, converted to LPS and validated.

    A ``ctdrill-plan/1`` file holds one trajectory and its landmarks; a Slicer ``.mrk.json``
    holds any number of Line markups (trajectories) and Curve/Fiducial markups (landmarks),
    possibly none of either (3D Slicer saves one markup per file).

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
        from ctdrill.imaging.plan.slicer import parse_slicer

        return parse_slicer(ctx, doc)
    if "format" not in doc:
        raise ctx.fail(
            "format",
            f'is missing; a plan starts with "format": "{PLAN_FORMAT}" '
            "(or is a 3D Slicer .mrk.json with markups)",
        )
    return _parse_ctdrill(ctx, doc)


def read_plans(path: str | os.PathLike[str]) -> tuple[Plan, ...]:
    """Every trajectory of one plan file, each with the file's landmarks (see
    :func:`read_parts`); a file without a trajectory is refused."""
    from ctdrill.imaging.plan.merge import merge_parts

    return merge_parts([read_parts(path)])
