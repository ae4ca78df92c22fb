"""Candidate axes around a planned one, for ``ctdrill suggest`` (docs/suggest.md).

Candidate 0 is the planned axis itself, entry and target exactly as planned. Candidates
``1 .. count - 1`` are points of a 4-dimensional Halton sequence (bases 2, 3, 5, 7; the
first point, all zeros, skipped), ``(h1, h2, h3, h4)`` in ``[0, 1)^4``, mapped to

- an **anchor** ``A = E + rho (cos phi e1 + sin phi e2)`` in the plane through the planned
  entry ``E`` perpendicular to the planned axis ``u`` (``e1, e2`` from
  :func:`ctdrill.imaging.sampling.lip.axis_basis`), ``rho = radius sqrt(h1)``,
  ``phi = 2 pi h2``: uniform over the disc's area;
- a **direction** ``d = cos theta u + sin theta (cos psi e1 + sin psi e2)`` with
  ``cos theta = 1 - h3 (1 - cos cone)``, ``psi = 2 pi h4``: uniform over the cone's solid
  angle.

The candidate's **entry** is where its own line ``A + t d`` first meets bone
(:func:`ctdrill.imaging.sampling.surface.first_bone_crossing_mm`, threshold owned by
:mod:`ctdrill.imaging.misch`), searched over ``|t| <= SURFACE_SEARCH_MM``; its target is
``entry + depth d`` with the planned depth. So every candidate's drill meets no bone above
its entry (within the search), and the radius bounds where its axis crosses the planned entry
plane. A line with no surface there keeps ``A`` as its entry and is marked (never evaluated,
never feasible). With a seed, the whole sequence is shifted by one uniform random vector
modulo 1 (a Cranley-Patterson rotation): another equally even set, reproducible by its seed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ctdrill.app.errors import AppInputError
from ctdrill.app.search.defaults import DEFAULT_CONE_DEG, DEFAULT_COUNT, DEFAULT_RADIUS_MM
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.sampling.lip import axis_basis
from ctdrill.imaging.sampling.surface import first_bone_crossing_mm
from ctdrill.imaging.volume import CTVolume

#: How far along each candidate's line, before and after its anchor, the bone surface is
#: searched, mm.
SURFACE_SEARCH_MM = 10.0
#: Bounds of the options: a radius beyond a few teeth or a cone past 45 degrees is no longer
#: "around the planned axis"; the count bounds memory and time (about 2 ms per candidate).
MAX_RADIUS_MM = 20.0
MAX_CONE_DEG = 45.0
MAX_COUNT = 100_000
_BASES = (2, 3, 5, 7)


class SuggestInputError(AppInputError):
    """Bad settings for ``ctdrill suggest`` (the message names the option)."""


@dataclass(frozen=True)
class SearchSpace:
    """Where candidates are sampled.

    Attributes
    ----------
    radius_mm : largest distance of a candidate's anchor from the planned entry, in the plane
        perpendicular to the planned axis, mm.
    cone_deg : largest angle between a candidate's axis and the planned one, degrees.
    count : candidates in all, the planned axis included.
    seed : None for the plain Halton sequence (deterministic), else the seed of its random
        shift.
    """

    radius_mm: float = DEFAULT_RADIUS_MM
    cone_deg: float = DEFAULT_CONE_DEG
    count: int = DEFAULT_COUNT
    seed: int | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.radius_mm) and 0.0 <= self.radius_mm <= MAX_RADIUS_MM):
            raise SuggestInputError(
                f"--radius-mm must be between 0 and {MAX_RADIUS_MM:g} mm, got {self.radius_mm!r}"
            )
        if not (math.isfinite(self.cone_deg) and 0.0 <= self.cone_deg <= MAX_CONE_DEG):
            raise SuggestInputError(
                f"--cone-deg must be between 0 and {MAX_CONE_DEG:g} degrees, got {self.cone_deg!r}"
            )
        if isinstance(self.count, bool) or not (
            isinstance(self.count, int) and 1 <= self.count <= MAX_COUNT
        ):
            raise SuggestInputError(
                f"--count must be a whole number from 1 to {MAX_COUNT}, got {self.count!r}"
            )
        if self.seed is not None and not (
            isinstance(self.seed, int)
            and 0 <= self.seed < 2**63
            and not isinstance(self.seed, bool)
        ):
            raise SuggestInputError(
                f"--seed must be a whole number from 0 to 2**63 - 1, got {self.seed!r}"
            )


@dataclass(frozen=True, eq=False)
class Candidates:
    """The candidate axes (row 0: the planned axis).

    Attributes
    ----------
    entries_lps, targets_lps : (N, 3) LPS mm.
    anchors_lps : (N, 3) where each axis crosses the planned entry plane, LPS mm.
    offset_mm : (N,) distance of the anchor from the planned entry, mm.
    tilt_deg : (N,) angle between the axis and the planned one, degrees.
    no_surface : (N,) the line has no bone surface within the search: its entry is its anchor
        and it is not evaluated (row 0, taken as planned, is False).
    planned_surface_mm : distance along the planned axis from the planned entry to the bone
        surface (> 0: the surface lies deeper than the planned entry), NaN when none is found.
    """

    entries_lps: np.ndarray
    targets_lps: np.ndarray
    anchors_lps: np.ndarray
    offset_mm: np.ndarray
    tilt_deg: np.ndarray
    no_surface: np.ndarray
    planned_surface_mm: float

    def __post_init__(self) -> None:
        for value in vars(self).values():
            if isinstance(value, np.ndarray):
                value.flags.writeable = False

    @property
    def size(self) -> int:
        """``N``."""
        return int(self.entries_lps.shape[0])


def halton(n: int, *, seed: int | None = None) -> np.ndarray:
    """(n, 4) points ``1 .. n`` of the Halton sequence in bases 2, 3, 5, 7 (point 0, the
    origin, skipped), shifted modulo 1 by one uniform vector of ``numpy.random.default_rng(
    seed)`` when ``seed`` is given."""
    index = np.arange(1, n + 1, dtype=np.int64)
    out = np.zeros((n, len(_BASES)))
    for col, base in enumerate(_BASES):
        i = index.copy()
        scale = 1.0 / base
        while np.any(i > 0):
            out[:, col] += (i % base) * scale
            i //= base
            scale /= base
    if seed is not None:
        out = np.mod(out + np.random.default_rng(seed).random(len(_BASES)), 1.0)
    return out


def make_candidates(volume: CTVolume, plan: Plan, space: SearchSpace) -> Candidates:
    """The candidate axes of ``space`` around ``plan`` on ``volume`` (module docstring)."""
    basis = axis_basis(plan.entry_lps, plan.target_lps)
    u, e1, e2 = basis
    depth = plan.planned_depth_mm
    h = halton(space.count - 1, seed=space.seed)
    rho = space.radius_mm * np.sqrt(h[:, 0])
    phi = 2.0 * np.pi * h[:, 1]
    cos_t = 1.0 - h[:, 2] * (1.0 - math.cos(math.radians(space.cone_deg)))
    sin_t = np.sqrt(np.clip(1.0 - cos_t**2, 0.0, 1.0))
    psi = 2.0 * np.pi * h[:, 3]
    radial = np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2
    anchors = plan.entry_lps + rho[:, None] * radial
    tilt_dir = np.cos(psi)[:, None] * e1 + np.sin(psi)[:, None] * e2
    dirs = cos_t[:, None] * u + sin_t[:, None] * tilt_dir
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    lines_o = np.vstack([plan.entry_lps[None], anchors])
    lines_d = np.vstack([u[None], dirs])
    t = first_bone_crossing_mm(
        volume, lines_o, lines_d, start_mm=-SURFACE_SEARCH_MM, stop_mm=SURFACE_SEARCH_MM
    )
    found = np.isfinite(t)
    found[0] = True  # the planned axis is taken as planned
    step = np.where(found, np.nan_to_num(t), 0.0)
    step[0] = 0.0
    entries = lines_o + step[:, None] * lines_d
    targets = entries + depth * lines_d
    cos_all = np.clip(lines_d @ u, -1.0, 1.0)
    return Candidates(
        entries_lps=entries,
        targets_lps=targets,
        anchors_lps=lines_o,
        offset_mm=np.linalg.norm(lines_o - plan.entry_lps, axis=1),
        tilt_deg=np.degrees(np.arccos(cos_all)),
        no_surface=~found,
        planned_surface_mm=float(t[0]),
    )
