"""A blind trial's ``table.json`` keeps its force table sealed to the trial (nothing in it names
or hints at the bone), and ``ctdrill assess`` recomputes the session from it."""

from __future__ import annotations

import json
import re
import sqlite3
from pathlib import Path

import numpy as np
import pytest

from ctdrill.app.cli import main
from ctdrill.app.exercise.bone_quality import TRIAL_CLASSES, write_bone_quality
from ctdrill.app.exercise.seal import TOKEN_ALPHABET
from ctdrill.app.rehearse import rehearse
from ctdrill.app.trainee.session_table import SessionTraceError, read_table, table_text
from ctdrill.haptics.assessment import AssessmentContext
from ctdrill.haptics.profile_table import ProfileTable

CLASS_WORDS = re.compile(r"\bD[1-5]\b|misch", re.IGNORECASE)
PLAN = "ab" * 32


def _context() -> AssessmentContext:
    depth = np.linspace(0.0, 20.0, 41)
    return AssessmentContext(
        planned_depth_mm=12.0,
        max_safe_depth_mm=10.8,
        goal_depth_mm=10.8,
        clearance_depth_mm=depth,
        clearance_mm=12.8 - depth,
    )


def test_a_sealed_table_opens_to_the_same_table_for_its_trial_only() -> None:
    table = ProfileTable.slab(s0_n=4.25, top_mm=0.5, bottom_mm=15.0, stop_depth_mm=10.8)
    plain = read_table("t", table_text(table, _context(), PLAN).encode())[0]
    text = table_text(table, _context(), PLAN, trial=("ex1", "trial-03"))
    doc = json.loads(text)
    assert "table" not in doc and doc["trial"] == {"exercise_id": "ex1", "trial": "trial-03"}
    assert set(doc["table_sealed"].split(":")[1]) <= set(TOKEN_ALPHABET)
    assert "4.25" not in text
    opened, _, plan = read_table("t", text.encode())
    assert plan == PLAN and opened.stop_depth_mm == plain.stop_depth_mm
    for name in ("s0_n", "s1_n", "s2_n", "freqs_hz"):
        assert np.array_equal(getattr(opened, name), getattr(plain, name))
    # bound to the trial: another trial's name, another plan or one symbol edited
    for edit in (
        {**doc, "trial": {"exercise_id": "ex1", "trial": "trial-04"}},
        {**doc, "plan_sha256": "cd" * 32},
        {**doc, "table_sealed": doc["table_sealed"][:-3] + "zzz"},
    ):
        with pytest.raises(SessionTraceError, match="table_sealed"):
            read_table("t", json.dumps(edit).encode())


@pytest.fixture(scope="module")
def blind(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    root = tmp_path_factory.mktemp("blind")
    trials = write_bone_quality(root / "trials", trials=2, seed=3, spacing_mm=1.0)
    out = root / "session"
    trial = root / "trials" / "trial-01"
    rehearse(
        dicom=trial / "ct", plan=trial / "plan.json", out=out, operator="push:12", duration_s=1.5
    )
    return out, trials[0].misch


def test_a_blind_sessions_table_names_no_class_and_assess_recomputes_from_it(
    blind: tuple[Path, str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    session, truth = blind
    text = (session / "table.json").read_text(encoding="utf-8")
    doc = json.loads(text)
    assert "table" not in doc and "s0_n" not in text and not CLASS_WORDS.search(text)
    summary = json.loads((session / "summary.json").read_text(encoding="utf-8"))
    db = tmp_path / "r.db"
    answer = next(c for c in TRIAL_CLASSES if c != truth)
    argv = ["assess", str(session), "--db", str(db), "--trainee", "ann", "--answer", answer]
    assert main(argv) == 0
    with sqlite3.connect(db) as conn:
        score = conn.execute("SELECT score FROM sessions").fetchone()[0]
    assert score == summary["assessment"]["score"]
    capsys.readouterr()
    # a table copied from another trial or edited is refused: one error line, nothing stored
    edited = tmp_path / "edited"
    edited.mkdir()
    for f in session.iterdir():
        (edited / f.name).write_bytes(f.read_bytes())
    doc["trial"]["trial"] = "trial-02"
    (edited / "table.json").write_text(json.dumps(doc), encoding="utf-8")
    argv[1], argv[3] = str(edited), str(tmp_path / "e.db")
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "table.json" in err and err.count("\n") == 1
