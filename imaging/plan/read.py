"""What the plan readers share: a file's parts, field validation with messages naming the
field path, LPS conversion and the trajectory builder.

The formats are described in :mod:`ctdrill.imaging.plan.types`; the readers built on this
module are :mod:`~ctdrill.imaging.plan.plan_file` (``ctdrill-plan/1``),
:mod:`~ctdrill.imaging.plan.slicer` (3D Slicer markups) and
:mod:`~ctdrill.imaging.plan.segmentation` (mask files), dispatched by
:mod:`ctdrill.imaging.plan.load`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ctdrill.imaging.plan.arch import arch_error
from ctdrill.imaging.plan.budget import DEFAULT_PLACEMENT
from ctdrill.imaging.plan.implants import ImplantInputError, ImplantSpec, implant_from_json
from ctdrill.imaging.plan.landmarks import (
    Landmark,
)
from ctdrill.imaging.plan.site import site_error
from ctdrill.imaging.plan.types import (
    _MAXIMA,
    DEFAULT_MIN_WALL_MM,
    MAX_COORDINATE_MM,
    DrillSpec,
    Plan,
    PlanInputError,
    is_series_hash,
)
from ctdrill.safeio import load_json
from ctdrill.warning_codes import LoadWarning

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
    warnings : warnings for the summary (e.g. ``markups_skipped``).
    arch : (K, 3) LPS mm dental arch of the file (``arch_mm``, an arch Curve), or None.
    """

    source: Path
    trajectories: tuple[Plan, ...] = ()
    landmarks: tuple[Landmark, ...] = ()
    notes: tuple[str, ...] = ()
    warnings: tuple[LoadWarning, ...] = field(default_factory=tuple)
    arch: np.ndarray | None = None


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
        self.warnings: list[LoadWarning] = []

    def parts(
        self,
        trajectories: tuple[Plan, ...],
        landmarks: tuple[Landmark, ...],
        arch: np.ndarray | None = None,
    ) -> PlanParts:
        """The file's parts with the notes and warnings gathered while reading it."""
        return PlanParts(
            self.path, trajectories, landmarks, tuple(self.notes), tuple(self.warnings), arch
        )

    def arch(self, val: object, fp: str, system: str) -> np.ndarray:
        """An arch polyline (``arch_mm``) in LPS, refused naming ``fp`` (``arch_mm[3] ...``)."""
        if not isinstance(val, list) or not all(isinstance(p, list | tuple) for p in val):
            raise self.fail(fp, "must be a list of [x, y, z] points in mm", _short(val))
        for i, p in enumerate(val):
            if len(p) != 3 or not all(_is_number(v) for v in p):
                raise self.fail(f"{fp}[{i}]", "must be 3 finite numbers [x, y, z] in mm", p)
        problem = arch_error(val, MAX_COORDINATE_MM)
        if problem is not None:
            raise PlanInputError(f"{self.path.name}: {fp}{problem}")
        return _to_lps(np.asarray(val, dtype=np.float64).reshape(-1, 3), system)

    def implant(self, val: object, fp: str) -> ImplantSpec:
        """An implant object (every key given), refused naming ``fp``."""
        try:
            return implant_from_json(val, where=fp, source=self.path.name)
        except ImplantInputError as exc:
            raise PlanInputError(str(exc)) from exc

    def site(self, val: object, fp: str) -> int:
        """An FDI implant site (:mod:`~ctdrill.imaging.plan.site`), refused naming ``fp``."""
        problem = site_error(val)
        if problem is not None:
            raise self.fail(fp, problem, val)
        return int(val)  # type: ignore[call-overload]

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
            or not all(_is_number(v) and abs(v) <= MAX_COORDINATE_MM for v in val)
        ):
            raise self.fail(
                fp,
                "must be a list of 3 finite numbers [x, y, z] in mm "
                f"(|v| <= {MAX_COORDINATE_MM:g})",
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


def _short(val: object) -> object:
    """``val`` for a message: a long list is cut to its length."""
    if isinstance(val, list) and len(val) > 4:
        return f"a list of {len(val)} items"
    return val


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
    implant: ImplantSpec | None = None,
    min_wall: float = DEFAULT_MIN_WALL_MM,
    site: int | None = None,
    placement: str = DEFAULT_PLACEMENT,
) -> Plan:
    """One trajectory of the file (its landmarks and arch are joined by :func:`merge_parts`)."""
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
        implant=implant,
        min_wall_mm=min_wall,
        site=site,
        placement=placement,
    )


def _stem(path: Path) -> str:
    name = path.name
    for suffix in (".mrk.json", ".json"):
        if name.lower().endswith(suffix):
            return name[: -len(suffix)]
    return path.stem
