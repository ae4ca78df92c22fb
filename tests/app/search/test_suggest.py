"""``suggest`` finds the best feasible axis of a volume where it is known in closed form
(tests/app/search/columns.py), every feasible row truly keeps the margins, and the outputs
reload into the same answers."""

from __future__ import annotations

import csv
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from ctdrill.app.search.candidates import SearchSpace, halton, make_candidates
from ctdrill.app.search.score import Objective
from ctdrill.app.search.suggest import Suggestion, suggest
from ctdrill.app.search.suggest_write import CSV_COLUMNS, write_suggestion
from ctdrill.engine.path import plan_path
from ctdrill.imaging.misch import BONE_HU, CORTICAL_HU
from ctdrill.imaging.plan.landmarks import PointLandmark
from ctdrill.imaging.plan.load import load_plan
from ctdrill.imaging.plan.types import series_uid_hash
from ctdrill.imaging.volume import CTVolume
from ctdrill.model.calibration import Calibration, load_calibration
from tests.app.search import columns

COUNT = 600


@pytest.fixture(scope="module")
def vol() -> CTVolume:
    return columns.columns_volume()


@pytest.fixture(scope="module")
def cal() -> Calibration:
    return load_calibration("bone-illustrative")


@pytest.fixture(scope="module")
def found(vol: CTVolume, cal: Calibration) -> Suggestion:
    return suggest(vol, columns.columns_plan(), cal, SearchSpace(count=COUNT))


@pytest.fixture(scope="module")
def vertical(vol: CTVolume, cal: Calibration) -> Suggestion:
    return suggest(vol, columns.columns_plan(), cal, SearchSpace(count=COUNT, cone_deg=0.0))


def _closed_form_score(objective: Objective) -> float:
    body, crest, apex, _ = columns.best_terms()
    return (
        objective.body_weight * (body - BONE_HU) / (CORTICAL_HU - BONE_HU)
        + objective.crest_weight * crest
        + objective.apex_weight * apex
    )


def test_the_best_axis_is_the_closed_form_one(vertical: Suggestion) -> None:
    found = vertical
    best = found.best_index
    assert best is not None
    body, crest, apex, entry_z = columns.best_terms()
    expected = _closed_form_score(found.objective)
    sc = found.scores
    # No feasible vertical axis beats the closed-form optimum, and the axes whose shells stay
    # inside B reach it (HU is exact on the surface up to the surface's bisection).
    assert np.nanmax(sc.total[found.feasible]) <= expected + 1e-5
    assert sc.total[best] == pytest.approx(expected, abs=1e-5)
    assert sc.body_hu[best] == pytest.approx(body, abs=0.05)
    assert (sc.crest_cortical[best], sc.apex_cortical[best]) == (crest, apex)
    entry = found.candidates.entries_lps[best]
    assert entry[2] == pytest.approx(entry_z, abs=1e-5)  # on the bone surface
    assert np.hypot(entry[0] - columns.B_X, entry[1]) <= columns.B_R - 1.75 + 1e-9
    # Shells a voxel diagonal inside B's voxelised edge read B alone.
    clear_of_edge = columns.B_R - 1.75 - columns.VOXEL_MM * np.sqrt(2.0)
    c = found.candidates
    inside = np.hypot(c.entries_lps[:, 0] - columns.B_X, c.entries_lps[:, 1]) < clear_of_edge
    assert inside.sum() >= 3
    assert np.allclose(sc.total[inside], expected, atol=1e-5)


def test_the_canal_makes_the_axes_through_a_infeasible(found: Suggestion) -> None:
    c = found.candidates
    through_a = np.hypot(c.entries_lps[:, 0] - columns.A_X, c.entries_lps[:, 1]) < 1.0
    assert through_a.sum() >= 10
    assert not found.feasible[through_a].any() and not found.passed[through_a].any()
    assert all(
        r.startswith("final drill (2 mm, to 10.00 mm): margin to 'canal'")
        for r in np.array(found.reason)[through_a]
    )


def test_ranking_feasible_first_by_score_and_the_plan_is_candidate_0(found: Suggestion) -> None:
    plan = columns.columns_plan()
    assert np.array_equal(found.candidates.entries_lps[0], plan.entry_lps)
    assert np.array_equal(found.candidates.targets_lps[0], plan.target_lps)
    order = found.order
    feas = found.feasible[order]
    n = int(feas.sum())
    assert feas[:n].all() and not feas[n:].any()
    scores = found.scores.total[order[:n]]
    assert np.all(np.diff(scores) <= 0.0)
    assert found.passed[0] == (found.stop_reason[0] == "planned_depth")
    assert (
        not found.feasible[0] and not found.passed[0]
    )  # the planned axis passes 2.5 mm from the canal line


def test_every_candidate_keeps_its_depth_radius_and_cone(found: Suggestion) -> None:
    c = found.candidates
    depth = np.linalg.norm(c.targets_lps - c.entries_lps, axis=1)
    assert np.allclose(depth, columns.DEPTH_MM, atol=1e-9)
    assert c.offset_mm.max() <= 3.0 + 1e-12 and c.tilt_deg.max() <= 15.0 + 1e-9
    assert not c.no_surface.any()  # a flat surface under every anchor
    # Entries on the surface: the HU there is the bone threshold.
    from ctdrill.imaging.sampling.surface import SURFACE_TOL_MM

    vol = columns.columns_volume()
    hu = vol.sample(c.entries_lps[1:])
    slope = (columns.B_HU - columns.AIR) / columns.VOXEL_MM  # steepest ramp, HU per mm
    assert np.all(np.abs(hu - BONE_HU) <= slope * SURFACE_TOL_MM * 1.01)


def test_feasible_rows_truly_keep_the_margins(
    found: Suggestion, vol: CTVolume, cal: Calibration
) -> None:
    plan = columns.columns_plan()
    feasible = found.order[: found.n_feasible]
    infeasible = found.order[found.n_feasible :]
    picks = [*feasible[:3], *feasible[:: max(1, len(feasible) // 4)], *infeasible[::97]]
    for i in picks:
        c = found.candidates
        r = plan_path(
            vol, replace(plan, entry_lps=c.entries_lps[i], target_lps=c.targets_lps[i]), cal
        )
        clear_at_plan = r.clearance_mm[-1]
        keeps = bool(np.all(clear_at_plan >= r.margins_mm)) and r.stop_reason == "planned_depth"
        assert keeps == bool(found.passed[i]), (i, r.stop_reason, clear_at_plan)
        assert keeps or not found.feasible[i]
        assert r.max_safe_depth_mm == pytest.approx(found.max_safe_depth_mm[i], abs=1e-9)
        assert r.plan_clearance_mm == pytest.approx(found.min_clearance_mm[i], abs=1e-9)


def test_outputs_reload_and_plan_path_reproduces_the_best_row(
    found: Suggestion, vol: CTVolume, cal: Calibration, tmp_path: Path
) -> None:
    out = tmp_path / "out"
    written = write_suggestion(found, out)
    assert sorted(p.name for p in written) == ["best.plan.json", "candidates.csv", "suggest.json"]
    rows = list(csv.DictReader((out / "candidates.csv").open(encoding="utf-8")))
    assert tuple(rows[0].keys()) == CSV_COLUMNS
    assert len(rows) == COUNT and sorted(int(r["candidate"]) for r in rows) == list(range(COUNT))
    top = rows[0]
    assert int(top["candidate"]) == found.best_index and top["feasible"] == "true"
    best = load_plan(out / "best.plan.json")
    entry = [float(top[f"entry_{a}_mm"]) for a in "xyz"]
    target = [float(top[f"target_{a}_mm"]) for a in "xyz"]
    assert best.entry_lps.tolist() == entry and best.target_lps.tolist() == target  # exact
    # Everything but the axis is kept; the series it was found on is recorded.
    plan = columns.columns_plan()
    assert best.drill == plan.drill and best.margin_mm == plan.margin_mm
    assert best.calibration == plan.calibration and best.name == plan.name
    assert [lm.name for lm in best.landmarks] == ["canal"]
    assert best.series_uid_sha256 == series_uid_hash(vol.info.series_uid)
    r = plan_path(vol, best, cal)
    assert r.stop_reason == "planned_depth"
    assert float(top["max_safe_depth_mm"]) == pytest.approx(r.max_safe_depth_mm, abs=1e-6)
    assert float(top["min_clearance_mm"]) == pytest.approx(r.plan_clearance_mm, abs=1e-6)
    assert float(top["body_hu"]) == pytest.approx(found.scores.body_hu[found.best_index], abs=1e-3)
    assert (top["passed"], top["checked"], top["problems"]) == ("true", "true", "")
    summary = json.loads((out / "suggest.json").read_text(encoding="utf-8"))
    assert summary["best_candidate"] == found.best_index
    assert summary["planned_rank"] == found.rank_of(0) and summary["n_feasible"] == found.n_feasible
    assert summary["n_checked"] == found.n_checked and summary["n_passed"] == found.n_passed


def test_no_feasible_candidate_writes_no_best_plan(
    vol: CTVolume, cal: Calibration, tmp_path: Path
) -> None:
    # A point 0.5 mm under the planned target with an 8 mm margin: every tip of the search
    # (within 3 + 10 tan 15 = 5.7 mm of the axis) is closer than that.
    guard = PointLandmark(name="guard", point_lps=np.array([0.0, 0.0, -10.5]), margin_mm=8.0)
    plan = columns.columns_plan(landmarks=(guard,))
    s = suggest(vol, plan, cal, SearchSpace(count=40))
    assert s.best_index is None and s.best_plan() is None and s.n_feasible == 0
    assert any(n.startswith("no feasible candidate") for n in s.notes)
    written = write_suggestion(s, tmp_path / "out")
    assert sorted(p.name for p in written) == ["candidates.csv", "suggest.json"]
    assert not (tmp_path / "out" / "best.plan.json").exists()


def test_sampling_is_deterministic_and_the_seed_shifts_it(vol: CTVolume) -> None:
    plan = columns.columns_plan()
    a = make_candidates(vol, plan, SearchSpace(count=50))
    b = make_candidates(vol, plan, SearchSpace(count=50))
    c = make_candidates(vol, plan, SearchSpace(count=50, seed=3))
    d = make_candidates(vol, plan, SearchSpace(count=50, seed=3))
    assert np.array_equal(a.entries_lps, b.entries_lps)
    assert np.array_equal(c.targets_lps, d.targets_lps)
    assert not np.allclose(a.entries_lps[1:], c.entries_lps[1:])
    assert np.array_equal(c.entries_lps[0], plan.entry_lps)


def test_halton_points_are_the_radical_inverses() -> None:
    h = halton(4)
    assert h[:, 0].tolist() == [0.5, 0.25, 0.75, 0.125]
    assert h[:, 1].tolist() == pytest.approx([1 / 3, 2 / 3, 1 / 9, 4 / 9])
    assert h[:, 2].tolist() == pytest.approx([0.2, 0.4, 0.6, 0.8])
    assert h[:, 3].tolist() == pytest.approx([1 / 7, 2 / 7, 3 / 7, 4 / 7])
    shifted = halton(4, seed=1)
    assert np.all((shifted >= 0.0) & (shifted < 1.0))
    assert not np.allclose(shifted, h)


def test_chunked_evaluation_gives_the_same_ranking(
    vol: CTVolume, cal: Calibration, monkeypatch: pytest.MonkeyPatch
) -> None:
    import ctdrill.app.search.suggest as mod

    plan = columns.columns_plan()
    whole = suggest(vol, plan, cal, SearchSpace(count=30))
    monkeypatch.setattr(mod, "CHUNK", 7)
    chunked = suggest(vol, plan, cal, SearchSpace(count=30))
    assert np.array_equal(whole.order, chunked.order)
    assert np.array_equal(whole.scores.total, chunked.scores.total, equal_nan=True)
    assert whole.reason == chunked.reason and np.array_equal(whole.feasible, chunked.feasible)


def test_a_drill_sequence_is_searched_with_its_final_drill_and_kept(
    vol: CTVolume, cal: Calibration, found: Suggestion, tmp_path: Path
) -> None:
    from ctdrill.engine.batch import evaluate_batch
    from ctdrill.engine.path import PathInputError

    plan = columns.columns_plan()
    pilot = replace(plan.drill, diameter_mm=plan.drill.diameter_mm / 2)
    seq = plan.with_drills((pilot, plan.drill))
    with pytest.raises(PathInputError, match="drills a sequence"):
        evaluate_batch(vol, seq, plan.entry_lps[None], plan.target_lps[None], cal)
    s = suggest(vol, seq, cal, SearchSpace(count=COUNT))
    # the pilot lies inside the final drill's solid: the same table as the single-drill plan's
    assert np.array_equal(s.order, found.order)
    assert np.array_equal(s.feasible, found.feasible)
    assert np.array_equal(s.scores.total, found.scores.total, equal_nan=True)
    write_suggestion(s, tmp_path / "out")
    best = load_plan(tmp_path / "out" / "best.plan.json")
    assert [d.diameter_mm for d in best.drills] == [pilot.diameter_mm, plan.drill.diameter_mm]
