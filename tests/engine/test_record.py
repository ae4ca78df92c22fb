"""The summary record: keys added by later versions are always written, and a summary written
before them still reads (a batch resumed over older row folders)."""

from __future__ import annotations

import dataclasses
import json

from ctdrill import api
from ctdrill.engine.summary import DrillStep, PlanOutcome, TrajectorySummary, read_summary
from ctdrill.resources import asset

ADDED = {
    "implant_clearance_mm": None,
    "implant_binding_landmark": None,
    "bone_walls": None,
    "overdrill_mm": 0.0,
    "clearance_accuracy_mm": None,
    "site": None,
    "margin_budget_mm": None,
    "margin_budget": None,
    "tooth_distance_mm": None,
}


def test_added_keys_are_written_and_an_older_summary_reads() -> None:
    demo = asset("demo")
    volume = api.load_series(demo / "ct")
    plan = api.load_plan(demo / "plan.json")
    summary = api.summarize(api.plan_path(volume, plan))
    doc = json.loads(json.dumps(summary.to_json()))
    assert set(ADDED) <= set(doc)  # written even when null (the contract's "null")
    assert doc["implant_clearance_mm"] is not None  # the demo plan has an implant
    older = {k: v for k, v in doc.items() if k not in ADDED}
    read = read_summary(older)
    assert isinstance(read, TrajectorySummary)
    for name, absent in ADDED.items():
        assert getattr(read.outcome, name) == absent
    assert read.outcome.stop_depth_mm == summary.outcome.stop_depth_mm
    # reading today's document gives the same record back
    assert read_summary(doc).to_json() == summary.to_json()


def test_every_added_field_is_named_here() -> None:
    """A new key marked ``added`` is listed above (so its absent value is checked)."""
    marked = {
        f.metadata.get("json_key", f.name)
        for cls in (PlanOutcome, TrajectorySummary, DrillStep)
        for f in dataclasses.fields(cls)
        if "json_absent" in f.metadata
    }
    assert marked == set(ADDED) | {"planned_depth_mm"}
