"""``suggest`` in a real mandible's shape (tests/imaging/real_mandible.py: a CT synthesised in a
TCIA mandible segmentation, its canals known): a planned axis that drills into the right
canal's margin is infeasible, and every axis the search offers instead keeps the canal's
margin by an independent distance (the drill's axis segment to the canal's centreline
polyline) and starts on the real bone's surface."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from ctdrill.app.search.candidates import SearchSpace
from ctdrill.app.search.suggest import Suggestion, suggest
from ctdrill.imaging.plan.landmarks import CanalLandmark
from ctdrill.imaging.plan.types import Plan
from ctdrill.model.calibration import load_calibration
from tests.imaging.real_mandible import RealMandible, real_mandible

MARGIN_MM = 2.0
#: The resampled mask's voxel, mm (real_mandible's default).
VOXEL_MM = 0.75


def _segment_to_polyline_mm(p: np.ndarray, q: np.ndarray, line: np.ndarray) -> float:
    """Least distance between the segment ``p``-``q`` and the polyline ``line`` (sampled along
    the segment every 0.01 mm; exact point-to-segment distances to the polyline)."""
    s = np.linspace(0.0, 1.0, max(2, int(np.linalg.norm(q - p) / 0.01) + 1))
    pts = p + s[:, None] * (q - p)
    a, b = line[:-1], line[1:]
    ab = b - a
    t = np.clip(np.einsum("nsk,sk->ns", pts[:, None] - a, ab) / np.einsum("sk,sk->s", ab, ab), 0, 1)
    return float(np.linalg.norm(pts[:, None] - (a + t[..., None] * ab), axis=2).min())


@pytest.fixture(scope="module")
def case() -> tuple[RealMandible, Plan, Suggestion, np.ndarray]:
    m = real_mandible()
    canal = m.canals_lps[0]
    over = canal[len(canal) // 2]
    entry = over + np.array([0.0, 0.0, 16.0])
    plan = Plan(
        entry_lps=entry,
        target_lps=over + np.array([0.0, 0.0, 1.5]),  # into the canal's margin
        landmarks=(CanalLandmark("right canal", canal, m.canal_radius_mm),),
        margin_mm=MARGIN_MM,
        arch_lps=m.arch_lps,
    )
    space = SearchSpace(radius_mm=4.0, cone_deg=15.0, count=48)
    found = suggest(m.volume, plan, load_calibration("bone-literature"), space)
    # each voxel's distance to the nearest bone voxel centre, mm
    outside_mm = ndimage.distance_transform_edt(~m.bone) * VOXEL_MM
    return m, plan, found, outside_mm


def test_the_axis_into_the_canals_margin_is_infeasible(
    case: tuple[RealMandible, Plan, Suggestion, np.ndarray],
) -> None:
    _, _, found, _ = case
    assert not found.feasible[0] and found.stop_reason[0] == "margin"


def test_every_feasible_axis_keeps_the_margin_and_starts_on_the_bone(
    case: tuple[RealMandible, Plan, Suggestion, np.ndarray],
) -> None:
    m, plan, found, outside_mm = case
    assert found.best_index is not None and found.n_feasible >= 3
    canal = m.canals_lps[0]
    need = m.canal_radius_mm + MARGIN_MM
    for i in np.flatnonzero(found.feasible):
        entry, target = found.candidates.entries_lps[i], found.candidates.targets_lps[i]
        assert np.linalg.norm(target - entry) == pytest.approx(plan.planned_depth_mm, abs=1e-6)
        # the drill's tip path stays radius + margin from the centreline (the drill's own
        # radius keeps it further: a necessary condition the engine must meet)
        assert _segment_to_polyline_mm(entry, target, canal) >= need - 0.01, i
        # the entry is where the line meets the real bone: its voxel touches the mask (shares
        # a face, an edge or a corner with a bone voxel; the 150 HU edge lies just outside)
        k = tuple(np.rint(m.volume.lps_to_index(entry[None])[0][::-1]).astype(int))
        assert outside_mm[k] <= np.sqrt(3.0) * VOXEL_MM + 1e-9, i
        assert m.depth_mm[k] <= VOXEL_MM, i  # not inside the bone
