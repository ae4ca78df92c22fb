"""Reading 3D Slicer markups (``.mrk.json``) into plans; the format is in
:mod:`ctdrill.imaging.plan.types`."""

from __future__ import annotations

from typing import Any

import numpy as np

from ctdrill.imaging.plan.landmarks import (
    DEFAULT_CANAL_RADIUS_MM,
    CanalLandmark,
    Landmark,
    PointLandmark,
)
from ctdrill.imaging.plan.read import (
    _coordinate_system,
    _Ctx,
    _drill_from,
    _make_plan,
    _stem,
    _to_lps,
)
from ctdrill.imaging.plan.types import (
    _DRILL_KEYS,
    DEFAULT_CALIBRATION,
    DEFAULT_FEED_MM_S,
    DEFAULT_MARGIN_MM,
    Plan,
)

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


def parse_slicer(ctx: _Ctx, doc: dict[str, Any]) -> tuple[Plan, ...]:
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
