"""A rehearsal's ``summary.json`` carries every field of the export's summary of the same plan
with the same values (``site`` among them), as the typed ``RehearsalSummary`` embeds it."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path
from typing import Any

import pytest

from ctdrill.app.cli import main
from ctdrill.engine.summary import EXPORT_FORMAT, REHEARSAL_FORMAT, TrajectorySummary
from tests.conftest import ASSETS

DEMO = ASSETS / "demo"
#: The export's keys a rehearsal does not carry: whether force.png was written beside it.
EXPORT_ONLY = {"plot"}


def _run(argv: list[str]) -> None:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    assert code == 0, err.getvalue()


def _summary(folder: Path) -> dict[str, Any]:
    doc: dict[str, Any] = json.loads((folder / "summary.json").read_text(encoding="utf-8"))
    return doc


@pytest.fixture(scope="module")
def outputs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, dict[str, Any]]:
    """The demo plan with ``site`` 36: its export and its rehearsal (with ``--hu-sigma``, so
    the band's fields are filled); the demo's own plan (no site) exported."""
    tmp = tmp_path_factory.mktemp("site")
    doc = json.loads((DEMO / "plan.json").read_text(encoding="utf-8"))
    doc["site"] = 36
    plan = tmp / "plan.json"
    plan.write_text(json.dumps(doc), encoding="utf-8")
    common = ["--dicom", str(DEMO / "ct"), "--plan", str(plan), "--hu-sigma", "30"]
    _run(["export", *common, "--out", str(tmp / "x")])
    session = ["--operator", "push:12", "--duration-s", "1"]
    _run(["rehearse", *common, *session, "--out", str(tmp / "r")])
    plain = ["--dicom", str(DEMO / "ct"), "--plan", str(DEMO / "plan.json")]
    _run(["export", *plain, "--out", str(tmp / "plain")])
    _run(["rehearse", *plain, *session, "--out", str(tmp / "plain_r")])
    return {name: _summary(tmp / name) for name in ("x", "r", "plain", "plain_r")}


def test_the_rehearsal_carries_every_field_of_the_export(outputs: dict[str, Any]) -> None:
    for export, rehearsal in ((outputs["x"], outputs["r"]), (outputs["plain"], outputs["plain_r"])):
        assert export["format"] == EXPORT_FORMAT and rehearsal["rehearsal"] == REHEARSAL_FORMAT
        differ = {
            k: (v, rehearsal.get(k, "missing"))
            for k, v in export.items()
            if k not in EXPORT_ONLY and rehearsal.get(k, "missing") != v
        }
        assert differ == {}
        # the contract's own list, named
        for k in ("stop_depth_mm", "max_safe_depth_mm", "binding_landmark", "min_clearance_mm"):
            assert rehearsal[k] == export[k] and export[k] is not None
        assert rehearsal["implant"] == export["implant"] and export["implant"] is not None
        assert rehearsal["warnings"] == export["warnings"] and export["warnings"]
        # a script reading an export's summary reads the rehearsal's
        assert TrajectorySummary.from_json(rehearsal).outcome == (
            TrajectorySummary.from_json(export).outcome
        )
        # the device's own stop beside the plan's: the plan's to float32
        assert rehearsal["device_stop_depth_mm"] == pytest.approx(export["stop_depth_mm"], abs=1e-4)
        assert rehearsal["session_duration_s"] == 1.0


def test_site_is_the_fdi_number_or_null(outputs: dict[str, Any]) -> None:
    assert outputs["x"]["site"] == 36 and outputs["r"]["site"] == 36
    assert "site" in outputs["plain"] and outputs["plain"]["site"] is None
    assert outputs["plain_r"]["site"] is None


def test_a_rehearsed_sequence_carries_the_exported_sequences_fields(tmp_path: Path) -> None:
    from ctdrill.imaging.plan.load import load_plan
    from ctdrill.imaging.plan.types import DrillSpec
    from ctdrill.imaging.plan.write import save_plan

    drills = (DrillSpec(diameter_mm=2.0), DrillSpec(diameter_mm=2.8))
    save_plan(load_plan(DEMO / "plan.json").with_drills(drills), tmp_path / "plan.json")
    common = ["--dicom", str(DEMO / "ct"), "--plan", str(tmp_path / "plan.json")]
    _run(["export", *common, "--out", str(tmp_path / "x")])
    # long enough for each drill to reach its stop (2.4 s at 12 N), so the hole drill 2 cuts
    # around is the one the export assumes (to the device's float32 stop)
    session = ["--operator", "push:12", "--duration-s", "3"]
    _run(["rehearse", *common, *session, "--out", str(tmp_path / "r")])
    export, rehearsal = _summary(tmp_path / "x"), _summary(tmp_path / "r")
    assert export["format"] == "ctdrill-sequence/1"  # the rehearsal's listing has its own
    skip = {"format", "drills"}
    assert {k: v for k, v in export.items() if k not in skip and rehearsal.get(k) != v} == {}
    for x, r in zip(export["drills"], rehearsal["drills"], strict=True):
        # the hole a drill cut around is as deep as the drill before it reached in its session
        same = {k: v for k, v in x.items() if k != "inner_holes"}
        assert {k: r.get(k) for k in same} == same
    for k in (1, 2):  # each drill's own summary: the export's drill summary
        x, r = _summary(tmp_path / "x" / f"drill_{k}"), _summary(tmp_path / "r" / f"drill_{k}")
        differ = {n for n, v in x.items() if n not in EXPORT_ONLY and r.get(n, "missing") != v}
        assert differ == (set() if k == 1 else {"inner_holes"})
