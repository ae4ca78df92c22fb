"""``ctdrill export`` of a drill sequence on the demo phantom: OUT/drill_k/ and summary.json."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import pytest

from ctdrill.app.cli import main
from ctdrill.imaging.plan.load import load_plan
from ctdrill.imaging.plan.types import DrillSpec
from ctdrill.imaging.plan.write import save_plan
from tests.conftest import ASSETS

DEMO = ASSETS / "demo"
DRILLS = (
    DrillSpec(diameter_mm=2.0, tip_length_mm=0.6),
    DrillSpec(diameter_mm=2.8, tip_length_mm=0.84),
    DrillSpec(diameter_mm=3.5, tip_length_mm=1.05),
)
FILES = ("force.csv", "force.png", "profile.csv", "summary.json")


def _run(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    return code, out.getvalue(), err.getvalue()


def _export(plan: Path, out: Path) -> str:
    code, stdout, err = _run(
        ["export", "--dicom", str(DEMO / "ct"), "--plan", str(plan), "--out", str(out)]
    )
    assert code == 0
    assert err == ""  # the progress goes to stdout
    return stdout


@pytest.fixture(scope="module")
def exported(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, str]:
    base = tmp_path_factory.mktemp("seq")
    plan = load_plan(DEMO / "plan.json").with_drills(DRILLS)
    (base / "seq").mkdir()
    save_plan(plan, base / "seq" / "plan.json")
    # the pilot alone, as a single-drill plan of the same file name
    (base / "pilot").mkdir()
    save_plan(plan.for_drill(0), base / "pilot" / "plan.json")
    stdout = _export(base / "seq" / "plan.json", base / "out")
    _export(base / "pilot" / "plan.json", base / "pilot_out")
    return base / "out", base / "pilot_out", stdout


def test_layout_one_folder_per_drill_and_a_listing_summary(
    exported: tuple[Path, Path, str],
) -> None:
    out, _, stdout = exported
    files = sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file())
    want = ["summary.json"] + [f"drill_{k}/{f}" for k in (1, 2, 3) for f in FILES]
    assert files == sorted(want)
    top = json.loads((out / "summary.json").read_text())
    assert top["format"] == "ctdrill-sequence/1" and top["final_drill"] == 3
    per = [json.loads((out / f"drill_{k}" / "summary.json").read_text()) for k in (1, 2, 3)]
    for k, (entry, doc) in enumerate(zip(top["drills"], per, strict=True)):
        assert entry["drill"] == k + 1 and entry["folder"] == f"drill_{k + 1}"
        assert entry["diameter_mm"] == DRILLS[k].diameter_mm == doc["drill"]["diameter_mm"]
        for key in ("stop_depth_mm", "stop_reason", "peak_force_n", "mean_force_n"):
            assert entry[key] == doc[key]
        assert [h["diameter_mm"] for h in entry["inner_holes"]] == [
            d.diameter_mm for d in DRILLS[:k]
        ]
        for h, earlier in zip(entry["inner_holes"], per[:k], strict=True):
            assert h["depth_mm"] == pytest.approx(earlier["stop_depth_mm"], abs=1e-4)
        assert doc.get("inner_holes", []) == entry["inner_holes"]
    # the final drill's stop rules the plan
    for key in ("stop_depth_mm", "stop_reason", "max_safe_depth_mm", "planned_depth_mm"):
        assert top[key] == per[-1][key]
    # each drill keeps its own margin to the canal below the target
    assert [d["stop_reason"] for d in top["drills"]] == ["margin"] * 3
    assert all(d["min_clearance_mm"] == pytest.approx(2.0, abs=1e-3) for d in top["drills"])
    codes = {w["code"] for doc in per for w in doc["warnings"]}
    assert {w["code"] for w in top["warnings"]} == codes
    lines = [ln for ln in stdout.splitlines() if not ln.startswith(("wrote ", "export ["))]
    assert lines[0].startswith("plan drill 1/3 (2 mm): stop at ")
    assert lines[3].startswith("plan: final drill stops at ")
    assert len([line for line in lines if " drill " in line and "stop at" in line]) == 3


def test_first_drill_is_the_single_drill_export_byte_for_byte(
    exported: tuple[Path, Path, str],
) -> None:
    out, pilot_out, _ = exported
    for name in FILES:
        if name != "summary.json":
            assert (out / "drill_1" / name).read_bytes() == (pilot_out / name).read_bytes(), name
    # the summaries differ by one warning: the pilot alone is a final drill too narrow for the
    # implant (a check of the whole plan, not of one drill)
    seq, alone = (
        json.loads((d / "summary.json").read_text()) for d in (out / "drill_1", pilot_out)
    )
    dropped = [w for w in alone["warnings"] if w["code"] == "final_drill_mismatch"]
    assert len(dropped) == 1 and "the final drill (2 mm)" in dropped[0]["message"]
    alone["warnings"] = [w for w in alone["warnings"] if w not in dropped]
    assert seq == alone


def test_later_drills_cut_less_where_the_pilot_has_been(exported: tuple[Path, Path, str]) -> None:
    """In bone the 2.8 mm drill above the pilot's stop cuts the annulus: its s_t stays at or
    below the share 1 - 1.0/1.4 of the lip (uniform radial weighting)."""
    import csv

    out, _, _ = exported
    top = json.loads((out / "summary.json").read_text())
    pilot_stop = top["drills"][0]["stop_depth_mm"]
    with (out / "drill_2" / "profile.csv").open(newline="") as fh:
        rows = [r for r in csv.DictReader(fh) if float(r["depth_mm"]) < pilot_stop - 0.05]
    share = 1 - 1.0 / 1.4
    assert max(float(r["s_t"]) for r in rows) <= share + 1e-3
    assert max(float(r["s_t"]) for r in rows) >= share - 1e-3  # fully in bone somewhere
