"""The bone walls around an implant body, read from the CT's own samples.

For every depth along the body (platform to apex) and every direction perpendicular to its
axis, the **wall** is the distance from the implant's surface outward, along that direction,
to the **jaw's outer envelope**: the cortical surface of the bone the implant sits in, not the
first dark sample. CT numbers are trilinear samples
(:meth:`~ctdrill.imaging.volume.CTVolume.sample`), as everywhere else; *bone* is a sample at or
above the lower edge of Misch D4 (:data:`~ctdrill.imaging.misch.BONE_HU`, 150 HU).

**The envelope rule** (a closing along each ray; it holds in D4 and in fatty marrow, where the
cancellous bone between the implant and the cortex reads 50-150 HU or below): along the ray the
jaw ends at the first of

- a run of non-bone at least :data:`ENVELOPE_GAP_MM` (3 mm) long after bone has been met (the
  soft tissue outside the cortex; marrow spaces and the canal inside the jaw are shorter and
  are closed over), or
- a sample below :data:`AIR_HU` (air is never inside the jaw: a sinus, the mouth, a socket),

and the wall is the distance to the last bone/non-bone crossing before that end (bisected to
:data:`BISECT_TOL_MM` on the trilinear CT). A surface point whose ray meets no bone before the
end, or none within :data:`ENVELOPE_REACH_MM` (8 mm), lies **outside** the envelope: its wall
is 0, except a ray running along the jaw (within 45 deg of its long direction at that depth:
perpendicular to the arch's buccal direction, or without an arch to the mean axis of the rays
that cross the jaw's surface): the jaw goes on there (the wall reads ``max_wall_mm``). A ray
that meets no bone before the CT ends is judged the same way (across the jaw: outside).
Cancellous bone of any density between the implant and an intact cortex is therefore inside
the jaw and counts in the wall.

- **Outside the CT is unknown, never bone.** A direction whose ray leaves the CT (or reaches
  padding) before its end is decided has no wall: it counts in ``unknown_fraction``, not in the
  minimum, and the warning ``bone_walls_unknown`` says so.
- **Rays.** Each ray is sampled every ``ray_step_mm`` out to ``max_wall_mm`` plus the gap; a
  ray whose jaw goes on past ``max_wall_mm`` reads ``max_wall_mm`` ("at least"; ``capped``).
- **Sides.** With a dental arch the angular grid starts at the arch's buccal normal
  (:func:`~ctdrill.imaging.sampling.arch.buccal_normal_lps`) projected perpendicular to the
  axis; ``buccal_mm`` is the thinnest wall over the directions within 90 deg of it,
  ``lingual_mm`` over those within 90 deg of its opposite. Without an arch (or where it is
  straight or ends before the implant) both are None.
- **Perforation** means leaving the envelope: any surface point more than
  :data:`PERFORATION_DEPTH_MM` below the platform (the side, and the flat apex face along the
  axis) outside it: ``cortical_perforation``, reported with where it starts and which way. An
  apex inside a nerve canal is inside the jaw: it is named by ``canal_entry``
  (:mod:`ctdrill.imaging.plan.implant_safety`), not called a perforation.

Discretisation defaults (:data:`DEPTH_STEP_MM`, :data:`N_ANGLES`, :func:`ray_step_mm`) were
chosen by measured cost against error (docs/plan.md, "Bone walls").
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ctdrill.imaging.misch import BONE_HU
from ctdrill.imaging.plan.implants import ImplantPlacement, ImplantSpec, implant_placement
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.sampling.arch import buccal_normal_lps
from ctdrill.imaging.sampling.envelope import AIR_HU as AIR_HU
from ctdrill.imaging.sampling.envelope import BISECT_TOL_MM as BISECT_TOL_MM
from ctdrill.imaging.sampling.envelope import ENVELOPE_GAP_MM as ENVELOPE_GAP_MM
from ctdrill.imaging.sampling.envelope import ENVELOPE_REACH_MM as ENVELOPE_REACH_MM
from ctdrill.imaging.sampling.envelope import (
    MAX_ENVELOPE_MM,
    envelope_walls,
    start_ring_walls,
)
from ctdrill.imaging.volume import CTVolume

#: Surface points deeper than this below the platform must lie in bone, mm (above it the
#: platform may stand at or over a rounded crest).
PERFORATION_DEPTH_MM = 1.0
#: Depth step along the body, mm (the apex and platform always sampled).
DEPTH_STEP_MM = 0.25
#: Directions around the axis (every 5 deg).
N_ANGLES = 72
#: Ray step as a fraction of the CT's smallest voxel spacing (see :func:`ray_step_mm`).
RAY_STEP_VOXELS = 0.5

#: Walls are followed this far from the surface, mm (thicker walls read "at least" this).
MAX_WALL_MM = MAX_ENVELOPE_MM
#: Rays marched per chunk of steps (bounded memory; unresolved rays only).
_CHUNK_STEPS = 16


def ray_step_mm(volume: CTVolume) -> float:
    """The default ray step: :data:`RAY_STEP_VOXELS` of the CT's smallest spacing, mm (a cortex
    one voxel thick stays above the edge over about a voxel in the trilinear CT, so it is not
    stepped over; the crossing itself is bisected)."""
    return RAY_STEP_VOXELS * min(volume.spacing_mm)


@dataclass(frozen=True, eq=False)
class Perforation:
    """Where the implant surface leaves bone (below the perforation depth).

    Attributes
    ----------
    depth_mm : (shallowest, deepest) exposed depth from the entry along the trajectory, mm.
    below_platform_mm : the same below the platform, mm.
    point_lps : (3,) the shallowest exposed surface point.
    direction_lps : (3,) unit mean outward direction of the exposed side points (the axis
        direction when only the apex is exposed).
    fraction : exposed share of the surface samples below the perforation depth.
    """

    depth_mm: tuple[float, float]
    below_platform_mm: tuple[float, float]
    point_lps: np.ndarray
    direction_lps: np.ndarray
    fraction: float

    def to_json(self) -> dict[str, Any]:
        """The perforation as summaries write it."""
        return {
            "depth_mm": list(self.depth_mm),
            "below_platform_mm": list(self.below_platform_mm),
            "point_lps": self.point_lps.tolist(),
            "direction_lps": self.direction_lps.tolist(),
            "fraction": self.fraction,
        }


@dataclass(frozen=True, eq=False)
class BoneWalls:
    """The walls around one implant (see the module docstring); lengths in mm, LPS.

    Attributes
    ----------
    min_mm : the thinnest known wall (None when no direction is known).
    depth_mm : its depth from the entry along the trajectory; ``below_platform_mm`` the same
        from the platform.
    direction_lps : (3,) its outward direction.
    buccal_mm, lingual_mm : thinnest wall on each side of the arch (None without one).
    buccal_lps : (3,) the buccal direction used (perpendicular to the axis), or None.
    capped : ``min_mm`` is :data:`MAX_WALL_MM`: every known wall is at least that.
    unknown_fraction : share of the rays whose wall is unknown (the CT ends first).
    perforation : where the surface leaves bone, or None.
    depth_grid_mm : (D,) sampled depths from the entry; ``directions_lps`` (A, 3) the rays.
    wall_mm : (D, A) each ray's wall (NaN unknown; ``max_wall_mm`` capped).
    """

    min_mm: float | None
    depth_mm: float | None
    below_platform_mm: float | None
    direction_lps: np.ndarray | None
    buccal_mm: float | None
    lingual_mm: float | None
    buccal_lps: np.ndarray | None
    capped: bool
    unknown_fraction: float
    perforation: Perforation | None
    depth_grid_mm: np.ndarray
    directions_lps: np.ndarray
    wall_mm: np.ndarray

    def to_json(self) -> dict[str, Any]:
        """``bone_walls`` as a summary writes it (numbers in mm, directions LPS)."""
        return {
            "min_mm": self.min_mm,
            "depth_mm": self.depth_mm,
            "below_platform_mm": self.below_platform_mm,
            "direction_lps": None if self.direction_lps is None else self.direction_lps.tolist(),
            "buccal_mm": self.buccal_mm,
            "lingual_mm": self.lingual_mm,
            "capped": self.capped,
            "unknown_fraction": self.unknown_fraction,
            "perforation": None if self.perforation is None else self.perforation.to_json(),
            "bone_hu": BONE_HU,
        }


def plan_bone_walls(volume: CTVolume, plan: Plan, **options: Any) -> BoneWalls | None:
    """:func:`bone_walls` of ``plan``'s implant with its arch; None without an implant."""
    started = start_plan_bone_walls(volume, plan, **options)
    return None if started is None else started()


def start_plan_bone_walls(
    volume: CTVolume, plan: Plan, **options: Any
) -> Callable[[], BoneWalls] | None:
    """:func:`start_bone_walls` of ``plan``'s implant with its arch; None without an
    implant."""
    place = implant_placement(plan)
    if place is None:
        return None
    return start_bone_walls(volume, place, arch_lps=plan.arch_lps, **options)


@functools.lru_cache(maxsize=64)
def _body_depths(spec: ImplantSpec, depth_step_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """The depths below the platform the walls are read at (platform and apex included) and
    the body's radius at each, mm (read-only; the spec's own, computed once)."""
    n_d = max(2, math.ceil(spec.length_mm / depth_step_mm) + 1)
    s = np.linspace(0.0, spec.length_mm, n_d)
    r = np.array([spec.radius_at_mm(float(v)) for v in s])
    s.flags.writeable = False
    r.flags.writeable = False
    return s, r


def _frame(axis: np.ndarray, towards: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """Unit ``e1, e2`` perpendicular to ``axis``: ``e1`` along ``towards`` projected off the
    axis when it has a usable part, else along the world axis least aligned with ``axis``."""
    if towards is not None:
        e1 = towards - (towards @ axis) * axis
        if np.linalg.norm(e1) > 1e-6:
            e1 = e1 / np.linalg.norm(e1)
            return e1, np.cross(axis, e1)
    ref = np.eye(3)[int(np.argmin(np.abs(axis)))]
    e1 = ref - (ref @ axis) * axis
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(axis, e1)


def bone_walls(
    volume: CTVolume,
    placement: ImplantPlacement,
    *,
    arch_lps: np.ndarray | None = None,
    depth_step_mm: float = DEPTH_STEP_MM,
    n_angles: int = N_ANGLES,
    ray_step: float | None = None,
    max_wall_mm: float = MAX_WALL_MM,
) -> BoneWalls:
    """The bone walls around ``placement``'s body on ``volume`` (module docstring).

    Parameters
    ----------
    volume : the CT (HU).
    placement : the implant where the plan puts it.
    arch_lps : (K, 3) the dental arch (for buccal and lingual), or None.
    depth_step_mm, n_angles : depth step along the body (mm) and directions around it.
    ray_step : ray step, mm (default :func:`ray_step_mm`).
    max_wall_mm : how far each ray is followed, mm.
    """
    return start_bone_walls(
        volume,
        placement,
        arch_lps=arch_lps,
        depth_step_mm=depth_step_mm,
        n_angles=n_angles,
        ray_step=ray_step,
        max_wall_mm=max_wall_mm,
    )()


def start_bone_walls(
    volume: CTVolume,
    placement: ImplantPlacement,
    *,
    arch_lps: np.ndarray | None = None,
    depth_step_mm: float = DEPTH_STEP_MM,
    n_angles: int = N_ANGLES,
    ray_step: float | None = None,
    max_wall_mm: float = MAX_WALL_MM,
) -> Callable[[], BoneWalls]:
    """:func:`bone_walls` (same arguments) started: the rays begin on the worker threads
    (compiled kernel) and this returns at once a function that finishes them (lending the
    calling thread) and gives the :class:`BoneWalls`. A caller with other work (the drill's
    path of ``plan_path``) does it in between."""
    if not (depth_step_mm > 0.0 and n_angles >= 4 and max_wall_mm > 0.0):
        raise ValueError("bone walls: depth step and max wall must be > 0, n_angles >= 4")
    spec, axis = placement.spec, placement.axis_lps
    step = ray_step_mm(volume) if ray_step is None else float(ray_step)
    buccal = None if arch_lps is None else buccal_normal_lps(arch_lps, placement.platform_lps)
    e1, e2 = _frame(axis, buccal)
    theta = 2.0 * np.pi * np.arange(n_angles) / n_angles
    dirs = np.cos(theta)[:, None] * e1 + np.sin(theta)[:, None] * e2  # (A, 3)
    s, r = _body_depths(spec, float(depth_step_mm))
    surface = (
        placement.platform_lps + s[:, None, None] * axis + r[:, None, None] * dirs[None, :, :]
    )  # (D, A, 3)
    buccal_perp = (
        e1
        if buccal is not None and np.linalg.norm(buccal - (buccal @ axis) * axis) > 1e-6
        else None
    )
    rays = start_ring_walls(volume, surface, dirs, step, max_wall_mm, buccal_perp)

    def finish() -> BoneWalls:
        wall, unknown = rays()
        return _walls_of(
            volume, placement, wall, unknown, s, dirs, surface, buccal, e1, axis, step, max_wall_mm
        )

    return finish


def _walls_of(
    volume: CTVolume,
    placement: ImplantPlacement,
    wall: np.ndarray,
    unknown: np.ndarray,
    s: np.ndarray,
    dirs: np.ndarray,
    surface: np.ndarray,
    buccal: np.ndarray | None,
    e1: np.ndarray,
    axis: np.ndarray,
    step: float,
    max_wall_mm: float,
) -> BoneWalls:
    """The :class:`BoneWalls` of the rays' ``wall`` and ``unknown`` (D, A) of
    :func:`start_bone_walls`."""
    known = ~unknown
    depth = placement.platform_depth_mm + s
    out: dict[str, Any] = {"min_mm": None, "depth_mm": None, "below_platform_mm": None}
    direction = None
    if known.any():
        flat = np.where(known, wall, np.inf)
        d, a = np.unravel_index(int(np.argmin(flat)), flat.shape)
        out = {
            "min_mm": float(wall[d, a]),
            "depth_mm": float(depth[d]),
            "below_platform_mm": float(s[d]),
        }
        direction = dirs[a].copy()
    sides: dict[str, float | None] = {"buccal": None, "lingual": None}
    buccal_perp = None
    if buccal is not None and np.linalg.norm(buccal - (buccal @ axis) * axis) > 1e-6:
        buccal_perp = e1
        cos_b = dirs @ e1
        for name, cols in (("buccal", cos_b > 1e-9), ("lingual", cos_b < -1e-9)):
            part = np.where(known[:, cols], wall[:, cols], np.inf)
            sides[name] = float(part.min()) if np.isfinite(part).any() else None
    outside = known & (wall <= 0.0)
    perforation = _perforation(volume, placement, s, dirs, surface, outside, step)
    return BoneWalls(
        min_mm=out["min_mm"],
        depth_mm=out["depth_mm"],
        below_platform_mm=out["below_platform_mm"],
        direction_lps=direction,
        buccal_mm=sides["buccal"],
        lingual_mm=sides["lingual"],
        buccal_lps=buccal_perp,
        capped=out["min_mm"] is not None and out["min_mm"] >= max_wall_mm,
        unknown_fraction=float(unknown.mean()),
        perforation=perforation,
        depth_grid_mm=depth,
        directions_lps=dirs,
        wall_mm=np.where(unknown, np.nan, wall),
    )


def _perforation(
    volume: CTVolume,
    placement: ImplantPlacement,
    s: np.ndarray,
    dirs: np.ndarray,
    surface: np.ndarray,
    outside: np.ndarray,
    step: float,
) -> Perforation | None:
    """Surface points deeper than :data:`PERFORATION_DEPTH_MM` outside the jaw's envelope:
    the side (``outside`` (D, A), from the walls' rays) and a flat apex face (rays along the
    axis)."""
    spec, axis = placement.spec, placement.axis_lps
    deep = s > PERFORATION_DEPTH_MM
    flat = spec.apex == "flat" and spec.length_mm > PERFORATION_DEPTH_MM
    if not flat and not outside[deep].any():
        return None  # nothing exposed (what the arrays below would find)
    parts_p = [surface[deep].reshape(-1, 3)]
    parts_s = [np.repeat(s[deep], len(dirs))]
    parts_d = [np.tile(dirs, (int(deep.sum()), 1))]
    parts_x = [outside[deep].reshape(-1)]
    apex_r = spec.apex_diameter_mm / 2.0
    if flat:
        radii = apex_r * np.array([0.0, 1.0 / 3.0, 2.0 / 3.0])
        face = (placement.apex_lps + radii[:, None, None] * dirs[None, :, :]).reshape(-1, 3)
        along = np.broadcast_to(axis, face.shape)
        wall, unknown, open_ = envelope_walls(volume, face, np.ascontiguousarray(along), step=step)
        parts_p.append(face)
        parts_s.append(np.full(len(face), spec.length_mm))
        parts_d.append(along)
        # along the axis the jaw may hold more marrow than the reach: an open ray is inside
        parts_x.append(~unknown & ~open_ & (wall <= 0.0))
    pts = np.concatenate(parts_p)
    if len(pts) == 0:
        return None
    ss, out_dirs = np.concatenate(parts_s), np.concatenate(parts_d)
    exposed = np.concatenate(parts_x)
    if not exposed.any():
        return None
    first = int(np.argmin(np.where(exposed, ss, np.inf)))
    lat = out_dirs[exposed] - (out_dirs[exposed] @ axis)[:, None] * axis
    mean = lat.sum(axis=0)
    norm = float(np.linalg.norm(mean))
    direction = mean / norm if norm > 1e-9 * len(lat) else axis.copy()
    below = (float(ss[exposed].min()), float(ss[exposed].max()))
    return Perforation(
        depth_mm=(placement.platform_depth_mm + below[0], placement.platform_depth_mm + below[1]),
        below_platform_mm=below,
        point_lps=pts[first].copy(),
        direction_lps=direction,
        fraction=float(exposed.mean()),
    )
