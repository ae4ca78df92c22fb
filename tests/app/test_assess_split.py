"""The trainee record believes the trace, not the summary; it records how each session ran; the
curves and percentiles compare a session with the experts of the same case and mode only."""

from __future__ import annotations

import csv
import json
import shutil
import sqlite3
import unicodedata
from pathlib import Path
from typing import Any

import pytest

from ctdrill.app.cli import main
from ctdrill.app.trainee.record import open_record
from ctdrill.app.trainee.session_table import read_table, recompute
from tests.app.trainee_sessions import rewrite
from tests.conftest import ASSETS

DEMO = ASSETS / "demo"
WHEN = "2030-03-0{}T10:00:00+00:00"


def _rehearse(out: Path, *extra: str, operator: str = "human:force=12,react_ms=150") -> Path:
    argv = ["rehearse", "--dicom", str(DEMO / "ct"), "--plan", str(DEMO / "plan.json")]
    code = main([*argv, "--out", str(out), "--operator", operator, *extra])
    assert code in (0, 3)
    return out


@pytest.fixture(scope="module")
def sessions(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("split")
    return {
        "guarded": _rehearse(root / "guarded", "--duration-s", "2.6"),
        "exam": _rehearse(root / "exam", "--exam", "--duration-s", "3.2"),
        "fault": _rehearse(root / "fault", "--duration-s", "1.0", "--fault", "reset@0.4"),
    }


def _assess(*args: str | Path) -> int:
    return main(["assess", *(str(a) for a in args)])


def _one_error(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: "), err
    return err[0]


@pytest.mark.parametrize(
    ("field", "value"),
    [("score", 100.0), ("breach", False), ("overshoot_mm", 0.0), ("reaction_ms", None)],
)
def test_an_edited_summary_is_refused_naming_the_first_field_that_differs(
    sessions: dict[str, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    field: str,
    value: Any,
) -> None:
    # the instance: an exam that breached by 9.4 mm edited to score 100, breach false
    edited = tmp_path / "edited"
    shutil.copytree(sessions["exam"], edited)
    summary = json.loads((edited / "summary.json").read_text())
    assert summary["assessment"]["breach"] is True
    summary["assessment"][field] = value
    (edited / "summary.json").write_text(json.dumps(summary, indent=2))
    db = tmp_path / "record.sqlite"
    capsys.readouterr()
    assert _assess(edited, "--db", db, "--trainee", "eve") == 2
    line = _one_error(capsys)
    assert f"assessment.{field} is {value!r} but the session's trace gives" in line
    assert not db.exists() or open_record(db, create=False).sessions() == []


def test_a_space_added_to_an_experts_summary_is_the_same_session(
    sessions: dict[str, Path], tmp_path: Path
) -> None:
    db = tmp_path / "record.sqlite"
    assert _assess(sessions["guarded"], "--db", db, "--trainee", "dr-e", "--expert") == 0
    copy = tmp_path / "copy"
    shutil.copytree(sessions["guarded"], copy)
    (copy / "summary.json").write_text((copy / "summary.json").read_text() + " ")
    assert _assess(copy, "--db", db, "--trainee", "student") == 0
    rows = open_record(db, create=False).sessions()
    assert [(r["trainee"], r["expert"]) for r in rows] == [("dr-e", True)]


def test_rows_record_how_the_session_ran(sessions: dict[str, Path], tmp_path: Path) -> None:
    db = tmp_path / "record.sqlite"
    zoe_nfc = unicodedata.normalize("NFC", "Zoë")
    zoe_nfd = unicodedata.normalize("NFD", "ZOË")
    assert zoe_nfc != zoe_nfd
    assert _assess(sessions["guarded"], sessions["exam"], "--db", db, "--trainee", zoe_nfc) == 0
    assert _assess(sessions["fault"], "--db", db, "--trainee", zoe_nfd) == 0
    with sqlite3.connect(db) as conn:
        rows = conn.execute(
            "SELECT trainee, operator_kind, device_kind, mode, complete, outcome, reason, "
            "device_fault, program_version, goal_depth_mm, attempted FROM sessions "
            "ORDER BY mode, outcome"
        ).fetchall()
    assert {r[0] for r in rows} == {"zoë"}  # one trainee, however typed
    by_outcome = {(r[3], r[5]): r for r in rows}
    guarded = by_outcome[("guarded", "complete")]
    assert guarded[1:6] == ("scripted", "sim", "guarded", 1, "complete")
    assert guarded[7] == 0 and guarded[8] and guarded[9] == pytest.approx(10.8, abs=1e-3)
    assert by_outcome[("exam", "complete")][3] == "exam"
    fault = by_outcome[("guarded", "fault")]
    assert fault[4] == 0 and "device_reset" in fault[6] and fault[7] == 1


def test_percentiles_compare_the_same_case_and_mode_and_leave_faults_out(
    sessions: dict[str, Path], tmp_path: Path
) -> None:
    db = tmp_path / "record.sqlite"
    # experts: guarded sessions (perfect) and exam sessions (letting go later: deeper)
    guarded = [
        rewrite(sessions["guarded"], tmp_path / f"g{i}", WHEN.format(i), rest_rows=i + 1)
        for i in range(3)
    ]
    exam = [
        rewrite(sessions["exam"], tmp_path / f"e{i}", WHEN.format(i), depth_scale=1.0 + 0.02 * i)
        for i in range(3)
    ]
    assert (
        _assess(*guarded, *exam, sessions["fault"], "--db", db, "--trainee", "dr", "--expert") == 0
    )
    # the trainee's exam session: its overshoot ranks among the exam experts alone
    mine = rewrite(sessions["exam"], tmp_path / "mine", WHEN.format(8), depth_scale=1.01)
    assert _assess(mine, "--db", db, "--trainee", "sam", "--out", tmp_path / "curve") == 0
    with (tmp_path / "curve" / "percentiles.csv").open(newline="") as fh:
        pct = {r["metric"]: r for r in csv.DictReader(fh)}
    assert pct["score"]["mode"] == "exam" and pct["score"]["expert_sessions"] == "3"
    over = pct["overshoot_mm"]
    # deeper than the 1.00 expert, shallower than 1.02 and 1.04: better than two of three
    assert float(over["better_than_pct"]) == pytest.approx(100.0 * 2 / 3, abs=0.1)
    assert over["reads"] == "better than 66.7 % of the experts on this case and mode"
    depth = pct["depth_error_mm"]  # the smaller error is the better, whatever its sign
    assert float(depth["better_than_pct"]) == pytest.approx(100.0 * 2 / 3, abs=0.1)
    with (tmp_path / "curve" / "learning_curve.csv").open(newline="") as fh:
        curve = list(csv.DictReader(fh))
    assert [(r["mode"], r["expert_sessions"], r["ranked"]) for r in curve] == [("exam", "3", "1")]


def test_a_display_log_is_part_of_the_session(
    sessions: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # the window's display.csv: every 20 ms sample shown 435 ms late (a starved window)
    folder = tmp_path / "window"
    shutil.copytree(sessions["exam"], folder)
    lines = ["time_s,shown_s"] + [f"{0.02 * k:.4f},{0.02 * k + 0.435:.4f}" for k in range(160)]
    (folder / "display.csv").write_text("\n".join(lines) + "\n")
    db = tmp_path / "record.sqlite"
    capsys.readouterr()
    assert _assess(folder, "--db", db, "--trainee", "ann") == 2  # its summary says no lag
    assert "assessment.reaction_ms is" in _one_error(capsys)
    table, context, _ = read_table("t", (folder / "table.json").read_bytes())
    display = (folder / "display.csv").read_text()
    a = recompute("t", (folder / "session.csv").read_text(), table, context, display)
    summary = json.loads((folder / "summary.json").read_text())
    summary["assessment"] = a.to_json()
    (folder / "summary.json").write_text(json.dumps(summary))
    assert _assess(folder, "--db", db, "--trainee", "ann") == 0
    row = open_record(db, create=False).sessions()[0]
    assert row["display_lagged"] is True and row["display_lag_ms"] == pytest.approx(435.0)
    plain = json.loads((sessions["exam"] / "summary.json").read_text())["assessment"]
    assert row["reaction_ms"] < plain["reaction_ms"]  # timed from when it was shown


def test_experts_are_named_in_the_class_file(
    sessions: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    klass = tmp_path / "class.json"
    klass.write_text(
        json.dumps(
            {
                "format": "ctdrill-class/1",
                "roster": {"trainees": ["sam"], "experts": ["Dr-É"]},
                "exercises": [{"name": "demo", "mode": "guarded", "pass_mark": 50, "attempts": 3}],
            }
        )
    )
    db = tmp_path / "record.sqlite"
    expert = rewrite(sessions["guarded"], tmp_path / "x", WHEN.format(1), rest_rows=2)
    mine = rewrite(sessions["guarded"], tmp_path / "m", WHEN.format(2), depth_scale=0.9)
    # the expert typed another way is the roster's expert, without a flag
    nfd = unicodedata.normalize("NFD", "dr-é")
    assert _assess(expert, "--db", db, "--trainee", nfd, "--class", klass) == 0
    assert _assess(mine, "--db", db, "--trainee", "sam", "--class", klass) == 0
    rows = {r["trainee"]: r["expert"] for r in open_record(db, create=False).sessions()}
    assert rows == {"dr-é": True, "sam": False}
    out = tmp_path / "curve"
    assert _assess("--db", db, "--trainee", "sam", "--class", klass, "--out", out) == 0
    with (out / "percentiles.csv").open(newline="") as fh:
        score = next(r for r in csv.DictReader(fh) if r["metric"] == "score")
    assert score["expert_sessions"] == "1" and float(score["better_than_pct"]) == 0.0
    capsys.readouterr()
    other = rewrite(sessions["guarded"], tmp_path / "o", WHEN.format(3), rest_rows=3)
    assert _assess(other, "--db", db, "--trainee", "kim", "--expert") == 0
    assert "--expert is deprecated" in capsys.readouterr().err


#: A version 1 record's schema, as ctdrill wrote it before sessions recorded how they ran.
V1_SCHEMA = (
    "CREATE TABLE sessions (session_hash TEXT PRIMARY KEY, trainee TEXT NOT NULL, expert "
    "INTEGER NOT NULL CHECK (expert IN (0, 1)), plan_hash TEXT NOT NULL, recorded_at TEXT NOT "
    "NULL, stored_at TEXT NOT NULL, exam INTEGER NOT NULL CHECK (exam IN (0, 1)), operator "
    "TEXT, device TEXT, calibration TEXT, planned_depth_mm REAL, max_safe_depth_mm REAL, "
    "depth_error_mm REAL NOT NULL, overshoot_mm REAL NOT NULL, breach INTEGER NOT NULL CHECK "
    "(breach IN (0, 1)), time_in_margin_s REAL NOT NULL, canal_entered INTEGER NOT NULL CHECK "
    "(canal_entered IN (0, 1)), peak_hand_force_n REAL NOT NULL, mean_hand_force_n REAL NOT "
    "NULL, time_to_planned_s REAL, feed_cv REAL, reaction_ms REAL, wall_contacts INTEGER NOT "
    "NULL, peak_wall_force_n REAL NOT NULL, score REAL NOT NULL)",
    "CREATE INDEX sessions_by_trainee ON sessions (trainee, recorded_at)",
    "CREATE INDEX sessions_by_plan ON sessions (plan_hash, expert)",
    "CREATE TABLE traces (session_hash TEXT PRIMARY KEY REFERENCES sessions (session_hash), "
    "rate_hz REAL NOT NULL, samples INTEGER NOT NULL, time_s BLOB NOT NULL, master_mm BLOB NOT "
    "NULL, drill_mm BLOB NOT NULL, force_n BLOB NOT NULL)",
)


def test_a_version_1_record_is_migrated_and_keeps_its_rows(
    sessions: dict[str, Path], tmp_path: Path
) -> None:
    db = tmp_path / "old.sqlite"
    with sqlite3.connect(db) as conn:
        for statement in V1_SCHEMA:
            conn.execute(statement)
        conn.execute(
            "INSERT INTO sessions VALUES ('h1', 'ZOË', 0, 'p', '2029-01-01', '2029-01-01', 1, "
            "'human:force=12,react_ms=150', 'sim', 'bone-illustrative', 12.6, 10.8, 5.2, 6.4, "
            "1, 2.6, 1, 12.2, 11.9, 2.4, 0.42, 311.0, 0, 0.0, 4.8)"
        )
        conn.execute("INSERT INTO traces VALUES ('h1', 100.0, 0, x'', x'', x'', x'')")
        conn.execute("PRAGMA user_version = 1")
    conn.close()
    # storing a new session migrates the file in place (one transaction), the old row kept
    assert _assess(sessions["guarded"], "--db", db, "--trainee", "zoë") == 0
    with sqlite3.connect(db) as conn:
        assert conn.execute("PRAGMA user_version").fetchone()[0] == 2
        rows = conn.execute(
            "SELECT session_hash, trainee, mode, operator_kind, device_kind, score, attempted "
            "FROM sessions ORDER BY session_hash = 'h1' DESC"
        ).fetchall()
    conn.close()
    assert rows[0] == ("h1", "zoë", "exam", "scripted", "sim", 4.8, None)
    assert rows[1][1:5] == ("zoë", "guarded", "scripted", "sim") and rows[1][6] == 1
    out = tmp_path / "curve"
    assert _assess("--db", db, "--trainee", "Zoë", "--out", out) == 0  # one trainee
    with (out / "learning_curve.csv").open(newline="") as fh:
        assert {r["session_hash"] for r in csv.DictReader(fh)} == {"h1", rows[1][0]}
