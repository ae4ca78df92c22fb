"""Bone around the body, for many candidate axes at once: the CT numbers the score reads.

The **body** is the implant at its placement (apex at the candidate's target, platform
``length_mm`` back along the axis; :func:`~ctdrill.imaging.plan.implants.implant_placement`),
or, for a plan without an implant, the final drill's osteotomy (a cylinder of the drill's
radius from the entry to the planned depth). Along it, every :data:`DEPTH_STEP_MM` from its
top (platform) to its apex and in :data:`N_ANGLES` directions perpendicular to the axis, the
CT is sampled (trilinear, :meth:`~ctdrill.imaging.volume.CTVolume.sample`)

- on the **shell** at :data:`SHELL_MM` outside the body's surface: the bone the implant's
  threads engage (the score's terms, :mod:`ctdrill.app.search.score`);
- on the **surface** itself below the perforation depth
  (:data:`~ctdrill.imaging.sampling.walls.PERFORATION_DEPTH_MM`) and at ``min_wall_mm``
  outside it: a surface sample, or a sample at that distance, below the bone edge
  (:data:`~ctdrill.imaging.misch.BONE_HU`) flags the candidate as a **likely** perforation or
  thin wall. The flags only order the exact check (:mod:`ctdrill.app.search.feasibility`):
  flagged candidates are checked after the others; they decide nothing.

Outside the CT (or on padding) a sample is unknown: it counts as air (never bone) in the
score, and does not raise a flag.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ctdrill.app.search.shell_kernel import SHELL_KERNEL
from ctdrill.hu import AIR_HU
from ctdrill.imaging.misch import BONE_HU
from ctdrill.imaging.plan.implants import implant_placement
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.sampling.kernel_args import fits, volume_args
from ctdrill.imaging.sampling.walls import PERFORATION_DEPTH_MM
from ctdrill.imaging.teeth import TOOTH_HU, is_tooth_hu
from ctdrill.imaging.volume import CTVolume
from ctdrill.jit import row_spans, run_spans

#: Distances outside the body's surface where the score reads bone, mm: the first millimetre
#: around the implant, where its threads engage the bone.
SHELL_MM = (0.25, 0.75)
#: Depth step along the body, mm (its top and apex always sampled).
DEPTH_STEP_MM = 0.5
#: Directions around the axis.
N_ANGLES = 16
#: Candidates sampled per chunk (bounded memory: about 10 MB of points per chunk).
CHUNK = 256

#: What a shell sample in a tooth scores as: water (a tooth is not bone), HU.
TOOTH_SCORE_HU = 0.0


@dataclass(frozen=True, eq=False)
class BodyProfile:
    """The solid the score surrounds, on the sampling grid.

    Attributes
    ----------
    top_depth_mm : depth of its top (the implant's platform) from the entry, along the axis
        (negative when the implant stands above the entry), mm.
    s_mm : (D,) sampled depths below the top, mm.
    radius_mm : (D,) the body's radius there, mm.
    what : what the body is, for messages.
    """

    top_depth_mm: float
    s_mm: np.ndarray
    radius_mm: np.ndarray
    what: str

    @property
    def length_mm(self) -> float:
        """Top to apex, mm."""
        return float(self.s_mm[-1])


def body_profile(plan: Plan) -> BodyProfile:
    """The body of ``plan`` (module docstring); ``plan`` is the axis as drawn (target at the
    implant's apex)."""
    place = implant_placement(plan)
    if place is not None:
        spec = place.spec
        s = _grid(spec.length_mm)
        radius = np.array([spec.radius_at_mm(float(v)) for v in s])
        what = f"implant {spec.name!r} ({spec.size_text})"
        return BodyProfile(place.platform_depth_mm, s, radius, what)
    s = _grid(plan.planned_depth_mm)
    what = f"the final {plan.drill.diameter_mm:g} mm drill's osteotomy (no implant)"
    return BodyProfile(0.0, s, np.full(s.shape, plan.drill.radius_mm), what)


def _grid(length_mm: float) -> np.ndarray:
    return np.linspace(0.0, length_mm, max(2, math.ceil(length_mm / DEPTH_STEP_MM) + 1))


@dataclass(frozen=True, eq=False)
class ShellSamples:
    """What :func:`sample_shells` reads for ``N`` candidates.

    Attributes
    ----------
    hu : (N, D, A * len(SHELL_MM)) shell HU (outside the CT: air), NaN rows not sampled.
    likely_perforation : (N,) a surface sample deeper than the perforation depth is below
        the bone edge.
    likely_thin_wall : (N,) a sample ``min_wall_mm`` outside the surface is below it.
    """

    hu: np.ndarray
    likely_perforation: np.ndarray
    likely_thin_wall: np.ndarray


def axis_frames(directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N, 3) unit ``e1, e2`` perpendicular to each unit direction (N, 3): ``e1`` from the
    world axis least aligned with it."""
    helper = np.zeros_like(directions)
    helper[np.arange(len(directions)), np.argmin(np.abs(directions), axis=1)] = 1.0
    e1 = helper - np.sum(helper * directions, axis=1, keepdims=True) * directions
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    return e1, np.cross(directions, e1)


def sample_shells(
    volume: CTVolume,
    body: BodyProfile,
    entries_lps: np.ndarray,
    directions: np.ndarray,
    *,
    min_wall_mm: float,
) -> ShellSamples:
    """Shell HU and the two flags of each candidate axis (module docstring).

    Parameters
    ----------
    volume : the CT.
    body : the body (the same on every axis).
    entries_lps : (N, 3) each candidate's entry, LPS mm.
    directions : (N, 3) unit axis directions (entry -> target).
    min_wall_mm : the plan's thinnest wall to keep, mm.

    The compiled kernel (:mod:`~ctdrill.app.search.shell_kernel`) reads them when it is loaded
    and the volume has no padding; else the NumPy path below (the reference).
    """
    n = len(entries_lps)
    theta = 2.0 * np.pi * np.arange(N_ANGLES) / N_ANGLES
    offsets = np.array([*SHELL_MM, 0.0, min_wall_mm])  # shells, surface, wall
    radial = body.radius_mm[:, None] + offsets[None, :]  # (D, K)
    depth = body.top_depth_mm + body.s_mm  # (D,)
    deep = body.s_mm > PERFORATION_DEPTH_MM
    n_shell = len(SHELL_MM)
    hu_out = np.full((n, len(depth), N_ANGLES * n_shell), np.nan)
    perforation = np.zeros(n, dtype=bool)
    thin = np.zeros(n, dtype=bool)
    if n and fits(volume) and SHELL_KERNEL.ready():
        dirs = np.ascontiguousarray(directions, dtype=np.float64)
        e1, e2 = axis_frames(dirs)
        params = np.array([BONE_HU, TOOTH_HU, AIR_HU, TOOTH_SCORE_HU], dtype=np.float64)
        run_spans(
            SHELL_KERNEL,
            row_spans(np.arange(n)),
            *volume_args(volume),
            np.ascontiguousarray(entries_lps, dtype=np.float64),
            dirs,
            np.ascontiguousarray(e1),
            np.ascontiguousarray(e2),
            np.ascontiguousarray(depth, dtype=np.float64),
            np.ascontiguousarray(radial, dtype=np.float64),
            np.ascontiguousarray(deep),
            np.cos(theta),
            np.sin(theta),
            n_shell,
            params,
            hu_out,
            perforation,
            thin,
        )
        return ShellSamples(hu_out, perforation, thin)
    for lo in range(0, n, CHUNK):
        sl = slice(lo, min(lo + CHUNK, n))
        d = directions[sl]
        e1, e2 = axis_frames(d)
        cos, sin = np.cos(theta)[None, :, None], np.sin(theta)[None, :, None]
        ring = cos * e1[:, None] + sin * e2[:, None]  # (m, A, 3)
        centre = entries_lps[sl, None, :] + depth[None, :, None] * d[:, None, :]  # (m, D, 3)
        pts = (
            centre[:, :, None, None, :] + radial[None, :, None, :, None] * ring[:, None, :, None, :]
        )  # (m, D, A, K, 3)
        hu = volume.sample(pts, outside_hu=np.nan)
        shell = np.nan_to_num(hu[..., :n_shell], nan=AIR_HU)
        shell = np.where(is_tooth_hu(shell), TOOTH_SCORE_HU, shell)  # a tooth is not bone
        hu_out[sl] = shell.reshape(shell.shape[0], len(depth), -1)
        with np.errstate(invalid="ignore"):
            below = (hu < BONE_HU) | is_tooth_hu(hu)  # NaN (unknown): False
        perforation[sl] = below[..., n_shell][:, deep].any(axis=(1, 2))
        thin[sl] = below[..., n_shell + 1].any(axis=(1, 2))
    return ShellSamples(hu_out, perforation, thin)
