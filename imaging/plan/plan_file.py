"""Reading a ``ctdrill-plan/1`` document (the format: :mod:`ctdrill.imaging.plan.types`).

One trajectory at the top level (``entry_mm``, ``target_mm``, ``drill`` ...), or several in
``trajectories`` (a list of ``{name, entry_mm, target_mm, drill | drills, implant, feed_mm_s,
calibration, margin_mm}``, names unique); the landmarks, the arch (``arch_mm``) and the series
hash are the file's, shared by every trajectory. A file giving ``trajectories`` and a
trajectory's key (``entry_mm`` ...) at the top level is refused. A trajectory without a
``name`` is named by its ``site`` (the FDI number, ``36``) when it gives one not taken, else
after the file (its stem; ``STEM-N`` in a list).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ctdrill.imaging.plan.budget import DEFAULT_PLACEMENT, placement_error
from ctdrill.imaging.plan.drills import drills_field
from ctdrill.imaging.plan.landmarks import (
    DEFAULT_CANAL_RADIUS_MM,
    CanalLandmark,
    Landmark,
    PointLandmark,
)
from ctdrill.imaging.plan.mask import AXES
from ctdrill.imaging.plan.plan_keys import (
    _LANDMARK_KEYS,
    _PER_TRAJECTORY_KEYS,
    _TOP_KEYS,
    _TRAJECTORY_KEYS,
)
from ctdrill.imaging.plan.read import (
    PlanParts,
    _coordinate_system,
    _Ctx,
    _make_plan,
    _short,
    _stem,
    _to_lps,
    series_hash,
)
from ctdrill.imaging.plan.types import (
    DEFAULT_CALIBRATION,
    DEFAULT_FEED_MM_S,
    DEFAULT_MARGIN_MM,
    DEFAULT_MIN_WALL_MM,
    MAX_TRAJECTORIES,
    PLAN_FORMAT,
    SERIES_HASH_KEY,
    Plan,
)


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
    axes = raw.get("axes")
    if axes is not None and axes not in AXES:
        raise ctx.fail(
            f"{where}.axes",
            'must be "kji" (slices, rows, cols) or "ijk" (cols, rows, slices)',
            axes,
        )
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
        axes=axes,
    )


def parse_ctdrill(ctx: _Ctx, doc: dict[str, Any]) -> PlanParts:
    fmt = doc.get("format")
    if fmt != PLAN_FORMAT:
        raise ctx.fail("format", f'must be "{PLAN_FORMAT}"', fmt)
    ctx.keys(doc, _TOP_KEYS, "")
    system = _coordinate_system(ctx, doc, "coordinate_system", "")
    lms_raw = doc.get("landmarks", [])
    if not isinstance(lms_raw, list):
        raise ctx.fail("landmarks", "must be a list", lms_raw)
    base = ctx.path.parent
    landmarks = tuple(_parse_landmark(ctx, r, i, system, base) for i, r in enumerate(lms_raw))
    arch = ctx.arch(doc["arch_mm"], "arch_mm", system) if "arch_mm" in doc else None
    hashed = series_hash(ctx, doc.get(SERIES_HASH_KEY), SERIES_HASH_KEY)
    if "trajectories" not in doc:
        name = doc.get("name") if isinstance(doc.get("name"), str) else None
        plan = _trajectory(ctx, doc, "", system, hashed, name or _site_name(ctx, doc, "", ()))
        return ctx.parts((plan,), landmarks, arch)
    mixed = sorted(_PER_TRAJECTORY_KEYS & set(doc))
    if mixed:
        raise ctx.fail(
            mixed[0],
            "is given with trajectories; give each trajectory's settings inside its item of "
            "trajectories (the top level holds only what they share: landmarks, arch_mm)",
        )
    raw = doc["trajectories"]
    if not isinstance(raw, list) or not raw:
        raise ctx.fail("trajectories", "must be a non-empty list of trajectory objects", raw)
    if len(raw) > MAX_TRAJECTORIES:
        raise ctx.fail(
            "trajectories",
            f"lists {len(raw)} trajectories, more than the {MAX_TRAJECTORIES} a plan may hold; "
            "split the case into several plans",
        )
    plans: list[Plan] = []
    for i, item in enumerate(raw):
        where = f"trajectories[{i}]"
        if not isinstance(item, dict):
            raise ctx.fail(where, "must be a trajectory object", _short(item))
        ctx.keys(item, _TRAJECTORY_KEYS, where)
        taken = [p.name for p in plans]
        default = _site_name(ctx, item, where, taken) or f"{_stem(ctx.path)}-{i + 1}"
        name = ctx.string(item, "name", where, default=default)
        twin = next((k for k, p in enumerate(plans) if p.name == name), None)
        if twin is not None:
            raise ctx.fail(
                f"{where}.name",
                f"repeats the name of trajectories[{twin}]; name each trajectory once",
                name,
            )
        plans.append(_trajectory(ctx, item, where, system, hashed, name))
    return ctx.parts(tuple(plans), landmarks, arch)


def _site_name(ctx: _Ctx, obj: dict[str, Any], where: str, taken: Sequence[str]) -> str:
    """A trajectory without a name is named by its site (``36``) when it gives one not
    taken; else, alone in its file, by the file's stem ("" in a list: numbered there)."""
    pre = f"{where}." if where else ""
    if "site" in obj:
        site = str(ctx.site(obj["site"], pre + "site"))
        if site not in taken:
            return site
    return "" if where else _stem(ctx.path)


def _trajectory(
    ctx: _Ctx, obj: dict[str, Any], where: str, system: str, hashed: str | None, name: str
) -> Plan:
    """One trajectory's entry, target, drills, implant and settings (``obj`` at ``where``)."""
    pre = f"{where}." if where else ""
    for key in ("entry_mm", "target_mm"):
        if key not in obj:
            raise ctx.fail(pre + key, "is missing; add [x, y, z] in mm")
    entry = _to_lps(ctx.point(obj["entry_mm"], pre + "entry_mm"), system)
    target = _to_lps(ctx.point(obj["target_mm"], pre + "target_mm"), system)
    implant = ctx.implant(obj["implant"], pre + "implant") if "implant" in obj else None
    drills = drills_field(ctx, obj, where, implant)
    feed = ctx.number(obj, "feed_mm_s", where, default=DEFAULT_FEED_MM_S, positive=True)
    calibration = ctx.string(obj, "calibration", where, default=DEFAULT_CALIBRATION)
    margin = ctx.number(obj, "margin_mm", where, default=DEFAULT_MARGIN_MM, nonneg=True)
    wall = ctx.number(obj, "min_wall_mm", where, default=DEFAULT_MIN_WALL_MM, nonneg=True)
    site = ctx.site(obj["site"], pre + "site") if "site" in obj else None
    placement = obj.get("placement", DEFAULT_PLACEMENT)
    bad = placement_error(placement)
    if bad is not None:
        raise ctx.fail(pre + "placement", bad.split(", got")[0])
    return _make_plan(
        ctx,
        series_hash=hashed,
        entry=entry,
        target=target,
        drills=drills,
        feed=feed,
        calibration=calibration,
        margin=margin,
        name=name,
        field_path=pre + "target_mm",
        implant=implant,
        min_wall=wall,
        site=site,
        placement=placement,
    )
