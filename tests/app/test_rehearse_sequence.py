"""``ctdrill rehearse`` of a drill sequence on the demo phantom: one session per drill, each
drill's table cut around the hole the drill before it actually reached."""

from __future__ import annotations

import csv
import json
import shutil
import sqlite3
from pathlib import Path

import numpy as np
import pytest

from ctdrill.app.cli import main
from ctdrill.app.trainee.exam import plan_hash
from ctdrill.engine.path import plan_path
from ctdrill.engine.plans import plan_calibration
from ctdrill.engine.sequence import drill_path
from ctdrill.haptics.assessment import ASSESSMENT_FIELDS, combine_assessments
from ctdrill.imaging import load_series
from ctdrill.imaging.plan.load import load_plan
from ctdrill.imaging.plan.types import DrillSpec
from ctdrill.imaging.plan.write import save_plan
from ctdrill.model.profile import force_series_n

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "assets" / "demo"
DRILLS = (
    DrillSpec(diameter_mm=2.0, tip_length_mm=0.6),
    DrillSpec(diameter_mm=2.8, tip_length_mm=0.84),
)
FEED = 4.0


def _rows(path: Path) -> tuple[np.ndarray, np.ndarray]:
    with path.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    return np.array(
        [[float(r["time_s"]), float(r["drill_mm"]), float(r["force_cmd_n"])] for r in rows]
    ), np.array([r["state"] for r in rows])


@pytest.fixture(scope="module")
def rehearsed(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, int, str]:
    base = tmp_path_factory.mktemp("rehearse_seq")
    plan = load_plan(DEMO / "plan.json").with_drills(DRILLS)
    save_plan(plan, base / "plan.json")
    out = base / "out"
    import contextlib
    import io

    stdout = io.StringIO()
    with contextlib.redirect_stdout(stdout):
        code = main(
            [
                "rehearse",
                "--dicom",
                str(DEMO / "ct"),
                "--plan",
                str(base / "plan.json"),
                "--out",
                str(out),
                "--operator",
                f"feed:{FEED}",
                "--duration-s",
                "3.5",
            ]
        )
    return base / "plan.json", out, code, stdout.getvalue()


def test_one_session_per_drill_and_a_listing_summary(
    rehearsed: tuple[Path, Path, int, str],
) -> None:
    _, out, code, stdout = rehearsed
    assert code == 0
    files = sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file())
    assert files == [
        "drill_1/session.csv",
        "drill_1/summary.json",
        "drill_1/table.json",
        "drill_2/session.csv",
        "drill_2/summary.json",
        "drill_2/table.json",
        "summary.json",
    ]
    top = json.loads((out / "summary.json").read_text())
    one, two = (json.loads((out / f"drill_{k}" / "summary.json").read_text()) for k in (1, 2))
    assert top["format"] == "ctdrill-rehearsal-sequence/1"
    assert top["complete"] is True and (top["drills_run"], top["drills_planned"]) == (2, 2)
    assert top["stop_depth_mm"] == two["stop_depth_mm"]  # the final drill's stop rules
    assert [d["diameter_mm"] for d in top["drills"]] == [2.0, 2.8]
    assert "inner_holes" not in one and one["drill"]["diameter_mm"] == 2.0
    # the hole drill 2 cut around is as deep as drill 1 actually reached in its session
    assert two["inner_holes"] == [
        {"diameter_mm": 2.0, "tip_length_mm": 0.6, "depth_mm": one["max_drill_mm"]}
    ]
    assert top["drills"][0]["reached_depth_mm"] == one["max_drill_mm"]
    assert stdout.splitlines()[0].startswith("drill 1/2 (2 mm): stop depth ")


def test_drill_two_feels_the_annulus_force(rehearsed: tuple[Path, Path, int, str]) -> None:
    """At a steady feed the device renders S0(x) (1 + Ke v) (+ vibration, averaged out over
    0.1 s windows): drill 2's force follows its annulus profile, some 3.5 times below what
    its full lip would give in the same bone."""
    plan_file, out, _, _ = rehearsed
    plan = load_plan(plan_file)
    volume = load_series(DEMO / "ct")
    cal = plan_calibration(plan)
    one = json.loads((out / "drill_1" / "summary.json").read_text())
    annulus = drill_path(volume, plan, 1, cal, [one["max_drill_mm"]]).profile
    full = plan_path(volume, plan.for_drill(1), cal).profile
    data, state = _rows(out / "drill_2" / "session.csv")
    t, x, f = data.T
    steady = (state == "cutting") & (x > 4.0) & (x < one["max_drill_mm"] - 1.0)
    assert steady.sum() > 500
    ratios, full_ratios = [], []
    for start in np.arange(t[steady][0], t[steady][-1] - 0.1, 0.1):
        w = steady & (t >= start) & (t < start + 0.1)
        if w.sum() < 50:
            continue
        v = (x[w][-1] - x[w][0]) / (t[w][-1] - t[w][0])
        want = force_series_n(annulus, x[w], v, np.full(w.sum(), np.nan))
        want_full = force_series_n(full, x[w], v, np.full(w.sum(), np.nan))
        ratios.append(f[w].mean() / want.mean())
        full_ratios.append(f[w].mean() / want_full.mean())
    assert len(ratios) >= 5
    assert np.median(ratios) == pytest.approx(1.0, abs=0.1)
    assert np.median(full_ratios) < 0.45


def test_gui_shows_the_final_drill_around_the_earlier_holes(
    rehearsed: tuple[Path, Path, int, str],
) -> None:
    """The window computes a sequence's final drill as the export's last folder and says
    which drill it is where it explains the auto-stop."""
    from ctdrill.app.gui.results import compute_path_view, stop_explanation
    from ctdrill.engine.sequence import plan_sequence

    plan_file = rehearsed[0]
    plan = load_plan(plan_file)
    volume = load_series(DEMO / "ct")
    view = compute_path_view(volume, plan)
    seq = plan_sequence(volume, plan, plan_calibration(plan))
    np.testing.assert_array_equal(view.result.profile.s0_n, seq.final.profile.s0_n)
    pilot_stop = seq.steps[0].stop_depth_mm
    assert stop_explanation(view.result).endswith(
        f" (drill 2, 2.8 mm, after 2 mm to {pilot_stop:.2f} mm)"
    )
    assert "drill" not in stop_explanation(seq.steps[0])


def test_a_fault_ends_the_sequence_and_says_how_far_it_got(
    rehearsed: tuple[Path, Path, int, str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    plan_file = rehearsed[0]
    out = tmp_path / "out"
    code = main(
        [
            "rehearse",
            "--dicom",
            str(DEMO / "ct"),
            "--plan",
            str(plan_file),
            "--out",
            str(out),
            "--operator",
            "push:20",
            "--duration-s",
            "0.6",
            "--fault",
            "link-loss@0.3",
        ]
    )
    assert code == 3
    files = sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file())
    assert files == [
        "drill_1/session.csv",
        "drill_1/summary.json",
        "drill_1/table.json",
        "summary.json",
    ]
    top = json.loads((out / "summary.json").read_text())
    assert top["complete"] is False and (top["drills_run"], top["drills_planned"]) == (1, 2)
    assert top["stop_depth_mm"] is None and top["stop_reason"] is None
    assert top["faults"] and all(f["drill"] == 1 for f in top["faults"])
    captured = capsys.readouterr()
    assert "1 of 2 drills run: the sequence ended early" in captured.out
    assert captured.err.strip().splitlines()[-1].startswith("error: the session ended early")


def test_every_drill_and_the_sequence_are_assessed(
    rehearsed: tuple[Path, Path, int, str],
) -> None:
    # Each drill's summary carries its own assessment (its own plan and stop); the listing
    # carries the sequence's, with the same fields, combined from the drills' and scored by
    # the same rule, against the whole plan (its hash names both drills).
    plan_file, out, _, stdout = rehearsed
    top = json.loads((out / "summary.json").read_text())
    drills = [json.loads((out / f"drill_{k}" / "summary.json").read_text()) for k in (1, 2)]
    for doc in drills:
        assert tuple(doc["assessment"]) == ASSESSMENT_FIELDS
        assert not doc["assessment"]["breach"] and doc["assessment"]["score"] >= 50.0
    assert tuple(top["assessment"]) == ASSESSMENT_FIELDS
    want = combine_assessments(
        [d["assessment"] for d in drills], drills_planned=2, planned_depth_mm=12.0
    )
    assert top["assessment"] == want.to_json()
    assert [d["score"] for d in top["drills"]] == [d["assessment"]["score"] for d in drills]
    whole = load_plan(plan_file)
    assert top["plan_sha256"] == plan_hash(whole)
    assert {d["plan_sha256"] for d in drills} == {plan_hash(whole.for_drill(k)) for k in (0, 1)}
    assert f"assessment: score {top['assessment']['score']:.1f}/100" in stdout


def test_assess_stores_a_sequence_as_one_session(
    rehearsed: tuple[Path, Path, int, str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # The sequence's folder is one session of the record: its listing's assessment and the
    # drills' logs one after the other as its trace; stored twice it stays one row. A drill's
    # own folder is that drill alone.
    _, out, _, _ = rehearsed
    db = tmp_path / "record.db"
    args = ["assess", str(out), str(out / "drill_2"), "--db", str(db), "--trainee", "ana"]
    assert main(args) == 0
    assert main(["assess", str(out), "--db", str(db), "--trainee", "ana"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert "stored" in lines[0] and "already in the record" in lines[2]
    top = json.loads((out / "summary.json").read_text())
    con = sqlite3.connect(db)
    try:
        rows = con.execute(
            "SELECT s.plan_hash, s.score, t.samples, t.time_s FROM sessions s "
            "JOIN traces t USING (session_hash) ORDER BY t.samples DESC"
        ).fetchall()
    finally:
        con.close()
    assert len(rows) == 2
    (plan_sha, score, samples, time_blob), drill_two = rows
    assert plan_sha == top["plan_sha256"] and score == top["assessment"]["score"]
    assert drill_two[0] != plan_sha
    # 3.5 s per drill at the trace's 100 Hz, the second drill's times after the first's
    time_s = np.frombuffer(time_blob, dtype=np.float32)
    assert samples == time_s.size == drill_two[2] + 350
    assert np.all(np.diff(time_s) > 0.0) and time_s[-1] == pytest.approx(7.0, abs=0.02)


def test_exam_mode_runs_every_drill_of_a_sequence(
    rehearsed: tuple[Path, Path, int, str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # In exam mode every drill's table runs 10 mm past the plan: a person pushing 12 N who
    # lets go 150 ms after the breakthrough takes the pilot into the canal, and the sequence
    # records the breach (below any guarded score). On hardware it is refused, as for one.
    plan_file = rehearsed[0]
    out = tmp_path / "exam"
    base = ["rehearse", "--dicom", str(DEMO / "ct"), "--plan", str(plan_file), "--out"]
    op = ["--operator", "human:force=12,react_ms=150", "--duration-s", "3.5", "--exam"]
    assert main([*base, str(out), *op]) == 0
    stdout = capsys.readouterr().out
    top = json.loads((out / "summary.json").read_text())
    # the listing and the lines give each drill's exam stop, not the guarded one (10.80 mm)
    for entry in top["drills"]:
        assert entry["device_stop_depth_mm"] == pytest.approx(22.0, abs=1e-4)
        assert entry["exam_stop_basis"] == "beyond_plan" and entry["stop_reason"] == "margin"
    assert stdout.startswith("drill 1/2 (2 mm): stop depth 22.00 mm (exam: beyond_plan), ")
    drills = [json.loads((out / f"drill_{k}" / "summary.json").read_text()) for k in (1, 2)]
    for doc in drills:
        assert doc["exam"]["enabled"] is True and doc["exam"]["stop_basis"] == "beyond_plan"
        assert doc["device_stop_depth_mm"] == pytest.approx(22.0, abs=1e-4)
    pilot = drills[0]["assessment"]
    assert pilot["breach"] and pilot["canal_entered"] and pilot["reaction_ms"] is not None
    a = top["assessment"]
    assert a["breach"] and a["canal_entered"] and a["score"] < 45.0
    assert a["overshoot_mm"] == max(d["assessment"]["overshoot_mm"] for d in drills)
    assert top["exam"]["enabled"] is True
    # on the robot exam mode runs (its wall at the canal's surface): an absent port is the
    # only refusal, before anything is written
    code = main([*base, str(tmp_path / "hw"), *op, "--device", "serial:/dev/ttyUSB9"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "cannot open serial port" in err[0]
    assert not (tmp_path / "hw").exists()


@pytest.mark.parametrize("damage", ["folder", "log"])
def test_assess_refuses_a_damaged_sequence_folder(
    rehearsed: tuple[Path, Path, int, str],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    damage: str,
) -> None:
    # A listing naming a folder outside the sequence, or a drill's log missing: one error line
    # naming it, exit 2, nothing written.
    out = tmp_path / "seq"
    shutil.copytree(rehearsed[1], out)
    if damage == "folder":
        top = json.loads((out / "summary.json").read_text())
        top["drills"][1]["folder"] = "../elsewhere"
        (out / "summary.json").write_text(json.dumps(top))
    else:
        (out / "drill_2" / "session.csv").unlink()
    db = tmp_path / "record.db"
    assert main(["assess", str(out), "--db", str(db), "--trainee", "ana"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:")
    assert ("../elsewhere" in err[0]) if damage == "folder" else ("drill_2/session.csv" in err[0])
    assert not db.exists()
