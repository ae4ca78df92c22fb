"""The plan's verdict, computed once: every drill as drilled, the implant, the set's checks;
the banner and suggest's feasibility read it."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ctdrill.app.search.feasibility import check_candidate
from ctdrill.engine.path import plan_path
from ctdrill.engine.plans import plan_calibration
from ctdrill.engine.verdict import plan_verdict
from ctdrill.imaging import load_series
from ctdrill.imaging.plan.load import load_plan
from ctdrill.imaging.plan.safety import clearance_profile_mm
from ctdrill.imaging.plan.types import DrillSpec
from ctdrill.warning_codes import WARNINGS, banner_codes
from tests.conftest import ASSETS

DEMO = ASSETS / "demo"


@pytest.fixture(scope="module")
def demo() -> tuple[object, object]:
    return load_series(DEMO / "ct"), load_plan(DEMO / "plan.json")


def test_the_demo_breaks_its_margin_by_drill_and_by_implant(demo: tuple) -> None:  # type: ignore[type-arg]
    volume, plan = demo
    plan = plan.with_drills((DrillSpec(diameter_mm=2.0), DrillSpec(diameter_mm=2.8)))
    v = plan_verdict(volume, plan)
    # every drill as drilled (apex plus its own tip), in closed form from imaging's clearance
    for k in range(2):
        want = clearance_profile_mm(replace(plan, landmarks=v.plan.landmarks).drilled(k))[0]
        assert np.allclose(v.drill_clearance_mm[k], want, atol=1e-12)
    assert v.osteotomy_mm[0] == pytest.approx(v.drill_clearance_mm[:, 0].min())
    assert int(v.osteotomy_drill[0]) == 1  # the wider drill's tip reaches deeper
    codes = [w.code for w in v.findings]
    assert {"plan_violates_margin", "implant_violates_margin"} <= set(codes)
    assert len(codes) == len({(w.code, w.message) for w in v.findings})  # each once
    shown = [w.code for w in v.problems()]
    assert shown == sorted(shown, key=banner_codes().index)
    assert all(WARNINGS[w.code].blocks_suggest for _, w in v.blocking())
    assert not v.feasible
    # suggest's feasibility is the verdict's blocking findings, a drill's named
    f = check_candidate(volume, plan)
    assert [w.code for w in f.problems] == [w.code for _, w in v.blocking()]
    assert f.problems[0].message.startswith("drill 1 (2 mm): plan 'plan': the planned path breaks")


def test_with_a_path_its_warnings_join_once(demo: tuple) -> None:  # type: ignore[type-arg]
    volume, plan = demo
    path = plan_path(volume, plan.drilled(0), plan_calibration(plan))
    v = plan_verdict(volume, plan, path=path)
    assert v.implant is path.implant  # the path's implant outcome, not a second one
    pairs = [(w.code, w.message) for w in v.findings]
    assert len(pairs) == len(set(pairs))
    assert {(w.code, w.message) for w in path.warnings} <= set(pairs)
    assert v.drill_findings == ((),)  # the path's own warnings say the drill's margin


def test_far_from_every_landmark_is_feasible(demo: tuple) -> None:  # type: ignore[type-arg]
    volume, plan = demo
    v = plan_verdict(volume, replace(plan, landmarks=(), implant=None))
    assert v.feasible and v.drill_clearance_mm.shape == (1, 0) and v.problems() == ()


def test_the_export_warns_of_what_the_banner_shows(demo: tuple) -> None:  # type: ignore[type-arg]
    """The export's warnings and the verdict agree on every banner problem: a single drill
    (the path given) and a drill sequence (each drill's path, none given to the verdict)."""
    from ctdrill.engine.sequence import plan_sequence
    from ctdrill.engine.verdict import banner_problems

    volume, plan = demo
    path = plan_path(volume, plan.drilled(0), plan_calibration(plan))
    assert set(plan_verdict(volume, plan, path=path).problems()) == set(
        banner_problems(path.warnings)
    )
    seq_plan = plan.with_drills((DrillSpec(diameter_mm=2.0), DrillSpec(diameter_mm=2.8)))
    seq = plan_sequence(volume, seq_plan, plan_calibration(seq_plan))
    exported = set(banner_problems(seq.warnings))
    assert set(plan_verdict(volume, seq_plan).problems()) == exported


def test_the_export_report_and_rehearsal_list_the_verdicts_findings() -> None:
    """One trajectory's export job carries its verdict; the export's summary, the report's
    entry and the rehearsal's summary list its findings, each the same warnings."""
    from ctdrill.app.rehearse import load_table
    from ctdrill.app.report.entries import report_entries
    from ctdrill.app.session_run import rehearsal_summary
    from ctdrill.engine.case import prepare_case
    from ctdrill.engine.settings import DEFAULTS
    from ctdrill.engine.summarize import job_summary

    case = prepare_case(DEMO / "ct", [DEMO / "plan.json"], DEFAULTS)
    (job,) = case.jobs
    assert job.verdict is not None
    findings = job.verdict.findings
    assert {w.code for w in findings} >= {"plan_violates_margin"}
    exported = job_summary(job.result, case.context, job.verdict).summary
    assert exported.warnings == findings
    (entry,) = report_entries(case)
    assert entry.summary.warnings == findings
    loaded = load_table(DEMO / "ct", DEMO / "plan.json")
    assert loaded.verdict is not None and loaded.verdict.findings == findings
    doc = rehearsal_summary(
        {},
        loaded.path,
        loaded.table,
        context=loaded.case,
        operator="push:20",
        device="sim",
        duration_s=1.0,
        seed=0,
        verdict=loaded.verdict,
    )
    assert doc["warnings"] == [{"code": w.code, "message": w.message} for w in findings]
