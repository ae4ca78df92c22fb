"""What the cross-section says about the current implant, live while it is dragged: its
angulation, its depth below the crest, its distance to the canal and its thinnest bone wall.

Headless; computed with the path in the controller's worker (:func:`implant_readout`) and shown
in words by the cross-section view (:func:`readout_text`).

- **Angulation**: the implant axis (apex to platform) against the vertical (LPS +z): the
  total tilt, and with a dental arch its two components in the arch's frame at the implant
  site: bucco-lingual (+: the platform leans buccally, away from the arch's centre) and
  mesio-distal (+: the platform leans mesially, toward the arch's middle).
- **Depth below the crest**: where the axis enters bone nearest the platform
  (:func:`crest_depth_mm`; the bone threshold of :mod:`ctdrill.imaging.misch`) to the platform
  (the apex without an implant), along the axis: positive below the crest (subcrestal),
  negative when the implant stands out above it.
- **Distance to the canal and thinnest wall**: :func:`implant_safety`, read from the path
  result's implant check (:func:`ctdrill.app.gui.problems.implant_check`, the one place
  these come from): the implant body's own clearance to the landmark with the least slack
  (without an implant the final drill's at the planned depth) and its bone walls (the
  thinnest wall, buccal and lingual), on the full grid also while the implant is dragged.
  Lengths are written with the digits the CT supports.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ctdrill.app.gui.problems import implant_check
from ctdrill.imaging import CTVolume
from ctdrill.imaging.misch import is_bone
from ctdrill.imaging.plan.implants import implant_placement
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.resolution import format_clearance_mm, volume_clearance_accuracy_mm
from ctdrill.imaging.sampling.arch import ArchCurve
from ctdrill.imaging.sampling.surface import SURFACE_STEP_MM, first_bone_crossing_mm
from ctdrill.imaging.sampling.walls import BoneWalls

if TYPE_CHECKING:
    from ctdrill.app.gui.results import PathView

#: How far above the entry the crest is looked for along the axis, mm (a platform planned
#: above the entry still finds the crest).
CREST_SEARCH_ABOVE_MM = 15.0


@dataclass(frozen=True)
class ImplantReadout:
    """The current implant's figures (None: not known, with ``*_note`` saying why).

    Attributes
    ----------
    tilt_deg : angle of the axis from the vertical, degrees.
    buccolingual_deg, mesiodistal_deg : its components in the arch frame, degrees (None
        without an arch, or beyond its ends).
    crest_depth_mm : the platform (or apex) below the crest along the axis, mm.
    crest_of : ``platform`` or ``apex``.
    canal_mm : clearance to the binding landmark (a canal, usually), mm; ``canal_name`` its
        name; ``canal_of`` what was measured (``implant body`` or ``drill at the planned
        depth``).
    wall_mm : the thinnest bone wall around the implant, mm (None: not known, ``wall_note``
        says why); ``buccal_mm``, ``lingual_mm`` each side's.
    accuracy_mm : what the CT lets these lengths claim, +- mm: they are written with the
        digits it supports (:func:`~ctdrill.imaging.resolution.format_clearance_mm`; 0:
        every digit).
    """

    tilt_deg: float
    buccolingual_deg: float | None = None
    mesiodistal_deg: float | None = None
    crest_depth_mm: float | None = None
    crest_of: str = "platform"
    canal_mm: float | None = None
    canal_name: str = ""
    canal_of: str = ""
    wall_mm: float | None = None
    wall_note: str = ""
    buccal_mm: float | None = None
    lingual_mm: float | None = None
    accuracy_mm: float = 0.0


def angulation_deg(
    plan: Plan, arch_lps: np.ndarray | None
) -> tuple[float, float | None, float | None]:
    """(tilt, bucco-lingual, mesio-distal) of ``plan``'s axis, degrees (module docstring)."""
    up = -plan.direction  # apex -> platform
    tilt = math.degrees(math.acos(float(np.clip(up[2], -1.0, 1.0))))
    if arch_lps is None:
        return tilt, None, None
    curve = ArchCurve(np.asarray(arch_lps, dtype=np.float64))
    at = nearest_arc_mm(np.asarray(arch_lps, dtype=np.float64), plan.target_lps)
    _o, tangent, normal = (v[0] for v in curve.frame(np.array([at])))
    centroid = np.mean(curve.point_xy(curve.grid_mm(1.0)), axis=0)
    here = curve.point_xy(np.array([at]))[0]
    buccal = normal if float((here - centroid) @ normal[:2]) >= 0.0 else -normal
    mesial = tangent if at < 0.5 * curve.length_mm else -tangent
    bl = math.degrees(math.atan2(float(up @ buccal), float(up[2])))
    md = math.degrees(math.atan2(float(up @ mesial), float(up[2])))
    return tilt, bl, md


def nearest_arc_mm(arch_lps: np.ndarray, point_lps: np.ndarray) -> float:
    """Arc length (along the arch's axial projection, mm) of the arch point nearest to
    ``point_lps`` seen from above: the site an implant stands at, in closed form (the
    readout's frame; the reformats' exact normal foot is
    :func:`~ctdrill.imaging.sampling.reformat.arc_position_mm`)."""
    xy = np.asarray(arch_lps, dtype=np.float64)[:, :2]
    p = np.asarray(point_lps, dtype=np.float64).reshape(3)[:2]
    a, d = xy[:-1], np.diff(xy, axis=0)
    length = np.linalg.norm(d, axis=1)
    t = np.clip(np.einsum("ij,ij->i", p - a, d) / np.maximum(length**2, 1e-300), 0.0, 1.0)
    gap = np.linalg.norm(a + t[:, None] * d - p, axis=1)
    k = int(np.argmin(gap))
    return float(np.concatenate([[0.0], np.cumsum(length)])[k] + t[k] * length[k])


def crest_depth_mm(volume: CTVolume, plan: Plan) -> tuple[float | None, str]:
    """The platform (or, without an implant, the apex) below the crest along the axis, mm,
    and which it is; None when the axis meets no bone surface.

    The crest is where the axis enters bone (``HU`` from below to at least the bone threshold,
    going down the axis) nearest the platform: the jaw's crest, not an opposing tooth above it
    nor a canal's far wall below. The axis is scanned every
    :data:`~ctdrill.imaging.sampling.surface.SURFACE_STEP_MM` from
    :data:`CREST_SEARCH_ABOVE_MM` above the entry to the apex; the crossing found is located
    exactly by :func:`~ctdrill.imaging.sampling.surface.first_bone_crossing_mm`."""
    place = implant_placement(plan)
    stop = plan.planned_depth_mm
    of, depth = ("apex", stop) if place is None else ("platform", place.platform_depth_mm)
    ts = np.arange(-CREST_SEARCH_ABOVE_MM, stop + 1e-9, SURFACE_STEP_MM)
    hu = volume.sample(plan.entry_lps + ts[:, None] * plan.direction, outside_hu=np.nan)
    bone = is_bone(hu)
    ups = np.flatnonzero(~bone[:-1] & bone[1:] & np.isfinite(hu[:-1]))
    if ups.size == 0:
        return None, of
    k = int(ups[np.argmin(np.abs(ts[ups] - depth))])
    t = first_bone_crossing_mm(
        volume,
        plan.entry_lps[None],
        plan.direction[None],
        start_mm=float(ts[k]),
        stop_mm=float(ts[k + 1]),
    )[0]
    return (None if not np.isfinite(t) else float(depth - t)), of


def implant_safety(
    volume: CTVolume, plan: Plan, view: PathView | None
) -> tuple[tuple[float, str, str] | None, BoneWalls | None]:
    """The implant's distance to the landmarks and its bone walls.

    Returns ``((clearance_mm, landmark name, what was measured) | None, walls | None)``: from
    the implant check of the path result ``view`` when it was computed for
    ``plan`` (:func:`~ctdrill.app.gui.problems.implant_check`, the one place these come
    from), else that check computed here; without an implant, the final drill's clearance at
    the planned depth from ``view``.
    """
    result = None if view is None or view.plan is not plan else view.result
    landmarks = plan.landmarks if result is None else result.landmarks  # masks on the grid
    own = None if view is None or result is None else view.implant
    check = own if own is not None else implant_check(volume, plan, landmarks)
    canal = None
    body = None if check is None else check.clearance
    if body is not None:
        canal = (body.binding_clearance_mm, body.names[body.binding], "implant body")
    elif check is None and result is not None and result.clearance_mm.size:
        at_plan = np.asarray(result.clearance_mm, dtype=np.float64)[-1]
        k = int(np.argmin(at_plan))
        canal = (float(at_plan[k]), result.landmarks[k].name, "drill at the planned depth")
    if check is None:
        return canal, None
    return canal, check.walls


def implant_readout(volume: CTVolume, plan: Plan, view: PathView | None = None) -> ImplantReadout:
    """Every figure of the readout for ``plan`` on ``volume`` (``view``: its path result;
    :func:`implant_safety`)."""
    tilt, bl, md = angulation_deg(plan, plan.arch_lps)
    crest, of = crest_depth_mm(volume, plan)
    canal, walls = implant_safety(volume, plan, view)
    note = "no implant" if walls is None else "the CT ends before bone does"
    return ImplantReadout(
        tilt_deg=tilt,
        buccolingual_deg=bl,
        mesiodistal_deg=md,
        crest_depth_mm=crest,
        crest_of=of,
        canal_mm=None if canal is None else canal[0],
        canal_name="" if canal is None else canal[1],
        canal_of="" if canal is None else canal[2],
        wall_mm=None if walls is None else walls.min_mm,
        wall_note=note,
        buccal_mm=None if walls is None else walls.buccal_mm,
        lingual_mm=None if walls is None else walls.lingual_mm,
        accuracy_mm=volume_clearance_accuracy_mm(volume),
    )


def readout_text(r: ImplantReadout) -> str:
    """The readout in one line (``tilt 12.0° (B 8.0°, M 9.0°) · platform 0.8 mm below the
    crest · canal 3.40 mm ('left mandibular canal', implant body) · thinnest wall 1.20 mm
    (B 1.20, Li 2.10)``)."""
    parts = [f"tilt {r.tilt_deg:.1f}°"]
    if r.buccolingual_deg is not None and r.mesiodistal_deg is not None:
        bl = "B" if r.buccolingual_deg >= 0 else "Li"
        md = "M" if r.mesiodistal_deg >= 0 else "D"
        parts[0] += f" ({bl} {abs(r.buccolingual_deg):.1f}°, {md} {abs(r.mesiodistal_deg):.1f}°)"
    if r.crest_depth_mm is None:
        parts.append("crest: no bone along the axis")
    elif r.crest_depth_mm >= 0:
        parts.append(f"{r.crest_of} {r.crest_depth_mm:.1f} mm below the crest")
    else:
        parts.append(f"{r.crest_of} {-r.crest_depth_mm:.1f} mm above the crest")

    def mm(value: float) -> str:
        return format_clearance_mm(value, r.accuracy_mm)

    if r.canal_mm is None:
        parts.append("canal: none traced")
    else:
        parts.append(f"canal {mm(r.canal_mm)} mm ({r.canal_name!r}, {r.canal_of})")
    if r.wall_mm is None:
        parts.append(f"thinnest wall: unknown ({r.wall_note})")
    else:
        wall = f"thinnest wall {mm(r.wall_mm)} mm"
        if r.buccal_mm is not None and r.lingual_mm is not None:
            wall += f" (B {mm(r.buccal_mm)}, Li {mm(r.lingual_mm)})"
        parts.append(wall)
    return " · ".join(parts)
