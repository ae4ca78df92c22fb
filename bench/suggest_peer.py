"""The previous objective of ``ctdrill suggest``, kept as the benchmark's peer.

Before issue 25 a search was: the candidates, one batch evaluation of the final drill to the
planned target (``evaluate_batch``), a score read on the drill's **axis** (the mean disc HU of
its cutting lip over the path, cortical fractions of the crest and apex zones of the path),
and the batch's stop reason (``planned_depth``) as the whole feasibility rule. The bone the
implant's surface meets, the implant's own margin, the other drills and the bone walls were
not read. This module times that pipeline beside the current one (``bench/bench_suggest.py``).
"""

from __future__ import annotations

import numpy as np

from ctdrill.app.search.candidates import SearchSpace, make_candidates
from ctdrill.engine.batch import evaluate_batch
from ctdrill.imaging.misch import BONE_HU, CORTICAL_HU, is_cortical
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.volume import CTVolume
from ctdrill.model.calibration import Calibration

#: The previous objective's zones along the path and weights (body, crest, apex).
ZONE_MM = 2.0
WEIGHTS = (1.0, 0.5, 0.5)


def previous_suggest(
    volume: CTVolume, plan: Plan, calibration: Calibration, space: SearchSpace
) -> tuple[int | None, int]:
    """(best feasible candidate or None, number feasible) by the previous rule and score."""
    final = plan.for_drill(len(plan.drills) - 1)
    cands = make_candidates(volume, final, space)
    rows = np.flatnonzero(~cands.no_surface)
    batch = evaluate_batch(
        volume, final, cands.entries_lps[rows], cands.targets_lps[rows], calibration
    )
    depth, hu = batch.depth_mm, batch.disc_hu
    ok = np.all(np.isfinite(hu), axis=1)
    d_plan = final.planned_depth_mm
    cortical = is_cortical(np.nan_to_num(hu))
    in_crest = depth <= min(ZONE_MM, d_plan) + 1e-9
    in_apex = depth >= max(0.0, d_plan - ZONE_MM) - 1e-9
    with np.errstate(invalid="ignore"):
        body = (np.nanmean(hu, axis=1) - BONE_HU) / (CORTICAL_HU - BONE_HU)
        crest = (cortical & in_crest).sum(axis=1) / in_crest.sum(axis=1)
        apex = (cortical & in_apex).sum(axis=1) / in_apex.sum(axis=1)
    total = WEIGHTS[0] * body + WEIGHTS[1] * crest + WEIGHTS[2] * apex
    feasible = ok & (np.asarray(batch.stop_reason) == "planned_depth")
    if not feasible.any():
        return None, 0
    best = rows[np.flatnonzero(feasible)[np.argmax(total[feasible])]]
    return int(best), int(feasible.sum())
