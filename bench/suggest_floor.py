"""The tight-loop floor of ``suggest``'s whole search (``bench_shells``): compiled loops that read
the CT samples the search reads and only sum them (no rule, no flag, no bisection).

What the search reads, per run of ``suggest``:

- every candidate's line where its entry is searched: ``SURFACE_SEARCH_MM`` either side of
  its anchor every ``SURFACE_STEP_MM`` (the bisection's few samples more are not counted);
- every evaluated candidate's shells (``sample_shells``: depths x directions x offsets);
- for every candidate checked exactly, its implant's bone walls: every ray from the body's
  surface, marched as far as the envelope rule needs to decide it (its wall plus the
  envelope's gap of non-bone, at most ``MAX_WALL_MM`` plus the gap; an unknown ray the whole
  march) and the bisection of its exit crossing (``ceil(log2(step / BISECT_TOL_MM))`` samples
  for a ray with a wall inside the march). The rays' full marches (the NumPy path's samples)
  are counted too, for comparison.

The clearances (the batch's and the exact check's) are distances to the landmarks' segments,
not samples of the CT: they are not in the floor. The floor runs on one thread.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from bench.shell_floor import RAY_FLOOR, SHELL_FLOOR
from ctdrill.app.search.candidates import SURFACE_SEARCH_MM
from ctdrill.app.search.shell import N_ANGLES, SHELL_MM, axis_frames, body_profile
from ctdrill.app.search.suggest import Suggestion
from ctdrill.imaging.plan.implants import implant_placement
from ctdrill.imaging.sampling.envelope import BISECT_TOL_MM, ENVELOPE_GAP_MM
from ctdrill.imaging.sampling.kernel_args import volume_args
from ctdrill.imaging.sampling.surface import SURFACE_STEP_MM
from ctdrill.imaging.sampling.walls import DEPTH_STEP_MM, MAX_WALL_MM, plan_bone_walls, ray_step_mm
from ctdrill.imaging.volume import CTVolume


@dataclass(frozen=True)
class SearchFloor:
    """The floor's loop and what it reads.

    Attributes
    ----------
    run : one pass of every loop.
    line_samples, shell_samples, wall_samples : samples read by each part.
    wall_full_samples : the wall rays' full marches (not read by the floor).
    """

    run: Callable[[], None]
    line_samples: int
    shell_samples: int
    wall_samples: int
    wall_full_samples: int

    @property
    def samples(self) -> int:
        """All samples read."""
        return self.line_samples + self.shell_samples + self.wall_samples


def search_floor(volume: CTVolume, s: Suggestion) -> SearchFloor:
    """The floor of the search that produced ``s`` (the same candidates, the same checked)."""
    vargs = volume_args(volume)
    cands = s.candidates
    dirs = np.ascontiguousarray(cands.targets_lps - cands.entries_lps)
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    # 1. the lines of the entry search
    n_t = math.ceil(2.0 * SURFACE_SEARCH_MM / SURFACE_STEP_MM - 1e-9) + 1
    line_o = np.ascontiguousarray(cands.anchors_lps - SURFACE_SEARCH_MM * dirs)
    line_n = np.full(cands.size, n_t, dtype=np.int64)
    line_out = np.empty(cands.size)
    # 2. the shells of the candidates with a surface
    rows = np.flatnonzero(~cands.no_surface)
    body = body_profile(s.plan.for_drill(len(s.plan.drills) - 1))
    entries = np.ascontiguousarray(cands.entries_lps[rows])
    sh_dirs = np.ascontiguousarray(dirs[rows])
    e1, e2 = axis_frames(sh_dirs)
    theta = 2.0 * np.pi * np.arange(N_ANGLES) / N_ANGLES
    radial = np.ascontiguousarray(
        body.radius_mm[:, None] + np.array([*SHELL_MM, 0.0, s.plan.min_wall_mm])[None, :]
    )
    depth = np.ascontiguousarray(body.top_depth_mm + body.s_mm)
    cos_t, sin_t = np.cos(theta), np.sin(theta)
    shell_out = np.empty(rows.size)
    # 3. the bone walls of every candidate checked exactly
    step = ray_step_mm(volume)
    march = math.ceil((MAX_WALL_MM + ENVELOPE_GAP_MM) / step) + 1
    bisect = math.ceil(math.log2(step / BISECT_TOL_MM))
    origins, ray_dirs, counts = [], [], []
    for i in np.flatnonzero(s.checked).tolist():
        plan = s.plan_of(i)
        place = implant_placement(plan)
        walls = plan_bone_walls(volume, plan)
        if place is None or walls is None:
            continue
        spec = place.spec
        n_d = max(2, math.ceil(spec.length_mm / DEPTH_STEP_MM) + 1)
        s_mm = np.linspace(0.0, spec.length_mm, n_d)
        r_mm = np.array([spec.radius_at_mm(float(v)) for v in s_mm])
        a = walls.directions_lps
        surface = (
            place.platform_lps + s_mm[:, None, None] * place.axis_lps + r_mm[:, None, None] * a
        )
        origins.append(surface.reshape(-1, 3))
        ray_dirs.append(np.tile(a, (n_d, 1)))
        wall = walls.wall_mm.reshape(-1)
        known = np.isfinite(wall)
        reach = np.minimum(np.where(known, wall, MAX_WALL_MM), MAX_WALL_MM) + ENVELOPE_GAP_MM
        n = np.minimum(np.ceil(reach / step).astype(np.int64) + 1, march)
        n += np.where(known & (wall < MAX_WALL_MM), bisect, 0)
        counts.append(n)
    ray_o = np.ascontiguousarray(np.concatenate(origins) if origins else np.empty((0, 3)))
    ray_v = np.ascontiguousarray(np.concatenate(ray_dirs) if ray_dirs else np.empty((0, 3)))
    ray_n = np.ascontiguousarray(
        np.concatenate(counts) if counts else np.empty(0, dtype=np.int64), dtype=np.int64
    )
    ray_out = np.empty(ray_o.shape[0])

    def run() -> None:
        RAY_FLOOR(*vargs, line_o, dirs, SURFACE_STEP_MM, line_n, line_out)
        SHELL_FLOOR(
            *vargs, entries, sh_dirs, e1, e2, depth, radial, cos_t, sin_t, shell_out
        )  # fmt: skip
        RAY_FLOOR(*vargs, ray_o, ray_v, step, ray_n, ray_out)

    return SearchFloor(
        run=run,
        line_samples=int(line_n.sum()),
        shell_samples=int(rows.size * depth.size * N_ANGLES * radial.shape[1]),
        wall_samples=int(ray_n.sum()),
        wall_full_samples=int(ray_o.shape[0] * march),
    )
