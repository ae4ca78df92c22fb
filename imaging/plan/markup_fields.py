"""Fields of one 3D Slicer markup: units, placed control points, settings, names.

Helpers of :mod:`ctdrill.imaging.plan.slicer` (the rules are described there).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ctdrill.imaging.plan.read import _Ctx, _stem, _to_lps
from ctdrill.imaging.plan.settings import SettingsSyntaxError, parse_settings

#: ``positionStatus`` values of a placed point (absent means placed, as in Slicer).
_PLACED = "defined"
_UNPLACED = ("preview", "undefined", "missing")
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
    (its index in ``controlPoints`` and itself). A setting given at two of these levels with
    different values is refused, naming both (neither wins silently)."""
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
        for key, value in found.items():
            _agree(ctx, out, key, value, fp)
            out[key] = value
            out.origin[key] = fp
    if isinstance(attrs, dict):
        for key, value in attrs.items():
            _agree(ctx, out, key, value, f"{where}.attributes")
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


def _same_value(a: Any, b: Any) -> bool:
    """One setting's two values mean the same (``2`` and ``2.0``; text by its words)."""
    if isinstance(a, str) and isinstance(b, str):
        return a.strip() == b.strip()
    try:
        return bool(float(a) == float(b))
    except (TypeError, ValueError):
        return bool(a == b)


def _agree(ctx: _Ctx, out: _Settings, key: str, value: Any, fp: str) -> None:
    """Refuse ``key`` given again at another level with a different value."""
    if key in out and not _same_value(out[key], value):
        raise ctx.fail(
            f"{fp}: setting {key}",
            f"is {value!r} here and {out[key]!r} in {out.origin[key]}; a setting given at the "
            "markup and at the control point must agree (readers differ on which one wins): "
            "keep one",
        )


def _name(ctx: _Ctx, settings: dict[str, Any], markup: dict[str, Any], only: bool) -> str | None:
    name = settings.get("name")
    if isinstance(name, str) and name.strip():
        return name
    label = markup.get("name")
    if isinstance(label, str) and label.strip():
        return label
    return _stem(ctx.path) if only else None


def _number(ctx: _Ctx, settings: _Settings, key: str, *, positive: bool = False) -> float | None:
    if key not in settings:
        return None
    where = settings.origin[key]
    return ctx.number(settings, key, where, positive=positive, nonneg=not positive)


#: Why an unnamed Curve is refused, and what to do.
UNNAMED_CURVE = (
    'has no name: name the canal, e.g. name="left IAN canal" in its first control point\'s '
    "description (3D Slicer keeps it), or give the markup a name; ctdrill takes no name or role "
    'from the file\'s name (a Curve is a canal unless its description says "arch")'
)


def _curve_name(ctx: _Ctx, settings: dict[str, Any], markup: dict[str, Any], where: str) -> str:
    """A canal Curve's name: its ``name=`` setting or its markup name, never the file's."""
    name = _name(ctx, settings, markup, only=False)
    if name is None:
        raise ctx.fail(f"{where} (Curve)", UNNAMED_CURVE)
    return name
