"""A class: the class file, grades, confusion matrices, the dashboard, merging stations."""

from __future__ import annotations

import csv
import io
import json
import sqlite3
import time
from pathlib import Path
from typing import Any

import pytest

from ctdrill.app.classroom.class_file import ClassExercise, ClassFile, ClassFileError, load_class
from ctdrill.app.classroom.grades import GRADE_COLUMNS, confusion_rows, grade_rows
from ctdrill.app.cli import main
from ctdrill.app.exercise.aids import aid_level
from ctdrill.app.exercise.bone_quality import TRIAL_CLASSES, write_bone_quality
from ctdrill.app.rehearse import rehearse
from ctdrill.app.trainee import record as record_module

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "assets" / "demo"


def _exercise(name: str, mode: str, **kw: Any) -> ClassExercise:
    args: dict[str, Any] = {
        "plan_sha256": None,
        "generator": "bone-quality" if mode == "bone-quality" else None,
        "aid_level": None,
        "calibration": None,
        "pass_mark": 70.0,
        "attempts": 2,
    }
    args.update(kw)
    return ClassExercise(name, mode, **args)


def _session(trainee: str, score: float, when: str, **kw: Any) -> dict[str, Any]:
    row = {
        "session_hash": f"{trainee}-{when}",
        "trainee": trainee,
        "recorded_at": when,
        "exam": False,
        "plan_hash": "p",
        "calibration": "bone-illustrative",
        "score": score,
    }
    return row | kw


def test_grades_count_the_allowed_attempts_and_leave_device_faults_out() -> None:
    cls = ClassFile(
        "c",
        ("ann", "bo"),
        (),
        (_exercise("guarded", "guarded"), _exercise("exam", "exam", pass_mark=40.0)),
    )
    sessions = [
        _session("ann", 60.0, "1"),
        _session("ann", 50.0, "2", outcome="fault", device_fault=True),  # the device's: left out
        _session("ann", 75.0, "3"),
        _session("ann", 99.0, "4"),  # over the allowance of 2: not graded
        _session("ann", 30.0, "5", exam=True, outcome="fault", device_fault=False),  # counts
        _session("bo", 20.0, "1", exam=True),
    ]
    rows = {(r["trainee"], r["exercise"]): r for r in grade_rows(cls, sessions, [])}
    assert list(next(iter(rows.values()))) == list(GRADE_COLUMNS)
    g = rows[("ann", "guarded")]
    assert (g["attempts"], g["over_allowance"], g["faulted"]) == (3, 1, 1)
    assert (g["best"], g["last"], g["passed"]) == (75.0, 75.0, True)
    e = rows[("ann", "exam")]
    assert (e["attempts"], e["best"], e["passed"]) == (1, 30.0, False)
    none = rows[("bo", "guarded")]
    assert (none["attempts"], none["best"], none["last"], none["passed"]) == (0, None, None, False)
    assert rows[("bo", "exam")]["best"] == 20.0


def _answer(trainee: str, exercise_id: str, trial: str, answer: str, truth: str) -> dict[str, Any]:
    return {
        "trainee": trainee,
        "session_hash": f"{trainee}-{exercise_id}-{trial}",
        "exercise": "bone-quality",
        "exercise_id": exercise_id,
        "trial": trial,
        "answer": answer,
        "truth": truth,
    }


def test_bone_quality_attempts_are_sets_of_trials_and_confusion_counts_them() -> None:
    cls = ClassFile("c", ("ann", "bo"), ("dr",), (_exercise("feel", "bone-quality"),))
    answers = [
        _answer("ann", "x", "t1", "D1", "D1"),
        _answer("ann", "x", "t2", "D3", "D2"),
        _answer("ann", "y", "t1", "D4", "D4"),
        _answer("bo", "x", "t1", "D2", "D1"),
        _answer("dr", "x", "t1", "D1", "D1"),  # an expert: not in the class's matrix
    ]
    blind_session = _session("ann", 66.0, "9", session_hash="ann-x-t1")
    grades = {r["trainee"]: r for r in grade_rows(cls, [blind_session], answers)}
    assert (grades["ann"]["attempts"], grades["ann"]["best"], grades["ann"]["last"]) == (
        2,
        100.0,
        100.0,
    )
    assert grades["ann"]["passed"] and not grades["bo"]["passed"]
    rows = confusion_rows(cls, answers)
    assert len(rows) == 3 * len(TRIAL_CLASSES)
    klass = {r["truth"]: r for r in rows if r["scope"] == "class"}
    assert (klass["D1"]["answered_D1"], klass["D1"]["answered_D2"], klass["D1"]["trials"]) == (
        1,
        1,
        2,
    )
    assert (klass["D2"]["answered_D3"], klass["D2"]["correct_pct"]) == (1, 0.0)
    assert klass["D3"]["trials"] == 0 and klass["D3"]["correct_pct"] is None
    # a blind session is not an attempt at the guarded exercise
    cls2 = ClassFile("c", ("ann",), (), (_exercise("g", "guarded"),))
    assert grade_rows(cls2, [blind_session], answers)[0]["attempts"] == 0


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"format": "x"}, "ctdrill-class/1"),
        ({"roster": {"trainees": []}}, "roster.trainees"),
        ({"roster": {"trainees": ["a", "a"]}}, "roster.trainees[1]"),
        ({"roster": {"trainees": ["a"], "experts": ["a"]}}, "both a trainee and an expert"),
        ({"exercises": [{"name": "e", "mode": "drill", "pass_mark": 1, "attempts": 1}]}, "mode"),
        (
            {"exercises": [{"name": "e", "mode": "guarded", "pass_mark": 101, "attempts": 1}]},
            "pass_mark",
        ),
        (
            {"exercises": [{"name": "e", "mode": "guarded", "pass_mark": 1, "attempts": 0}]},
            "attempts",
        ),
        (
            {"exercises": [{"name": "e", "mode": "stop-yourself", "pass_mark": 1, "attempts": 1}]},
            "aid_level",
        ),
        (
            {
                "exercises": [
                    {
                        "name": "e",
                        "mode": "stop-yourself",
                        "aid_level": "some",
                        "pass_mark": 1,
                        "attempts": 1,
                    }
                ]
            },
            "aid_level",
        ),
        (
            {"exercises": [{"name": "e", "mode": "bone-quality", "pass_mark": 1, "attempts": 1}]},
            "generator",
        ),
        (
            {
                "exercises": [
                    {
                        "name": "e",
                        "mode": "guarded",
                        "case": "nope.json",
                        "pass_mark": 1,
                        "attempts": 1,
                    }
                ]
            },
            "case",
        ),
        (
            {
                "exercises": [
                    {"name": "e", "mode": "guarded", "pass_mark": 1, "attempts": 1, "x": 1}
                ]
            },
            "'x'",
        ),
    ],
)
def test_a_bad_class_file_names_the_field(
    tmp_path: Path, change: dict[str, Any], field: str
) -> None:
    doc = {
        "format": "ctdrill-class/1",
        "roster": {"trainees": ["a"]},
        "exercises": [{"name": "e", "mode": "guarded", "pass_mark": 50, "attempts": 1}],
    } | change
    path = tmp_path / "class.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(ClassFileError, match=None) as info:
        load_class(path)
    assert field in str(info.value) and str(path) in str(info.value)


def test_a_class_file_takes_a_roster_list_and_key_aliases(tmp_path: Path) -> None:
    path = tmp_path / "class.json"
    doc = {
        "format": "ctdrill-class/1",
        "roster": ["ann", {"id": "bo"}, {"id": "dr", "role": "expert"}],
        "exercises": [
            {
                "name": "e",
                "mode": "stop-yourself",
                "aids": "no-plots",
                "pass_mark": 70,
                "attempts_allowed": 3,
                "case": {"ct": "ct", "plan": str(DEMO / "plan.json")},
            },
        ],
    }
    path.write_text(json.dumps(doc))
    cls = load_class(path)
    assert cls.trainees == ("ann", "bo") and cls.experts == ("dr",)
    ex = cls.exercises[0]
    assert (ex.aid_level, ex.attempts, ex.session_mode) == ("no-plots", 3, "stop-yourself:no-plots")
    assert ex.plan_sha256 is not None
    doc["roster"] = [{"id": "x", "role": "teacher"}]
    path.write_text(json.dumps(doc))
    with pytest.raises(ClassFileError, match="roster\\[0\\]"):
        load_class(path)


def test_a_class_file_reads_cases_levels_and_normalised_ids(tmp_path: Path) -> None:
    path = tmp_path / "class.json"
    path.write_text(
        json.dumps(
            {
                "format": "ctdrill-class/1",
                "name": "k",
                "roster": {"trainees": ["ann", "bo"], "experts": ["dr"]},
                "exercises": [
                    {
                        "name": "demo",
                        "mode": "stop-yourself",
                        "aid_level": "no-gauges",
                        "case": str(DEMO / "plan.json"),
                        "pass_mark": 65,
                        "attempts": 4,
                    },
                    {
                        "name": "bq",
                        "mode": "bone-quality",
                        "generator": "bone-quality",
                        "calibration": "bone-illustrative",
                        "pass_mark": 75,
                        "attempts": 1,
                    },
                ],
            }
        )
    )
    cls = load_class(path)
    assert cls.trainees == ("ann", "bo") and cls.experts == ("dr",)
    demo = cls.exercises[0]
    assert demo.session_mode == "stop-yourself:no-gauges" and demo.attempts == 4
    assert demo.plan_sha256 is not None and len(demo.plan_sha256) == 64


# ------------------------------------------------------------- stations, merge, the report
@pytest.fixture(scope="module")
def stations(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, Path, dict[str, str]]:
    """Three trainees on two stations: blind trials answered and guarded demo sessions."""
    root = tmp_path_factory.mktemp("class")
    trials = write_bone_quality(root / "trials", trials=4, seed=2, spacing_mm=1.0)
    truth = {t.name: t.misch for t in trials}
    plan = {"ann": ("A", 12), "bo": ("A", 16), "=cmd": ("B", 10)}
    for who, (station, force) in plan.items():
        db = root / f"station{station}.db"
        for t in trials[:2]:
            out = root / "s" / who / t.name
            rehearse(
                dicom=root / "trials" / t.name / "ct",
                plan=root / "trials" / t.name / "plan.json",
                out=out,
                operator=f"push:{force}",
                duration_s=1.0,
            )
            named = t.misch if who != "bo" else next(c for c in TRIAL_CLASSES if c != t.misch)
            argv = ["assess", str(out), "--answer", named, "--db", str(db), "--trainee", who]
            assert main(argv) == 0
        out = root / "s" / who / "demo"
        rehearse(
            dicom=DEMO / "ct",
            plan=DEMO / "plan.json",
            out=out,
            operator=f"push:{force}",
            duration_s=4.5,  # 10 N reaches the demo's goal after 4.15 s (docs/rehearse.md)
        )
        assert main(["assess", str(out), "--db", str(db), "--trainee", who]) == 0
    # ann also drills without the gauges, and once the link fails (the device's fault)
    db = root / "stationA.db"
    common = {"dicom": DEMO / "ct", "plan": DEMO / "plan.json", "operator": "push:12"}
    rehearse(out=root / "s" / "ann" / "aids", duration_s=3.0, aids=aid_level("no-gauges"), **common)
    faulted = rehearse(
        out=root / "s" / "ann" / "fault", duration_s=3.0, faults=["link-loss@0.5"], **common
    )
    assert not faulted["complete"]
    for name in ("aids", "fault"):
        assert (
            main(["assess", str(root / "s" / "ann" / name), "--db", str(db), "--trainee", "ann"])
            == 0
        )
    klass = root / "class.json"
    klass.write_text(
        json.dumps(
            {
                "format": "ctdrill-class/1",
                "name": "test",
                "roster": {"trainees": ["ann", "bo", "=cmd"], "experts": []},
                "exercises": [
                    {
                        "name": "feel",
                        "mode": "bone-quality",
                        "generator": "bone-quality",
                        "pass_mark": 75,
                        "attempts": 2,
                    },
                    {
                        "name": "demo",
                        "mode": "guarded",
                        "case": str(DEMO / "plan.json"),
                        "pass_mark": 50,
                        "attempts": 3,
                    },
                    {
                        "name": "no gauges",
                        "mode": "stop-yourself",
                        "aid_level": "no-gauges",
                        "pass_mark": 50,
                        "attempts": 2,
                    },
                ],
            }
        )
    )
    return root / "stationA.db", root / "stationB.db", klass, truth


def _count(db: Path, table: str) -> int:
    with sqlite3.connect(db) as conn:
        return int(conn.execute(f"SELECT COUNT(*) FROM {table}").fetchone()[0])


def test_merging_stations_is_idempotent(
    stations: tuple[Path, Path, Path, dict[str, str]], tmp_path: Path
) -> None:
    a, b, _, _ = stations
    merged = tmp_path / "class.db"
    for _ in range(2):
        assert main(["assess", "--merge", str(a), str(b), "--db", str(merged)]) == 0
        assert _count(merged, "sessions") == _count(a, "sessions") + _count(b, "sessions") == 11
        assert _count(merged, "traces") == 11 and _count(merged, "answers") == 6
    assert main(["assess", "--merge", str(a), str(merged), "--db", str(merged)]) == 0
    assert _count(merged, "sessions") == 11
    with sqlite3.connect(merged) as conn:
        modes = dict(conn.execute("SELECT mode, COUNT(*) FROM sessions GROUP BY mode").fetchall())
    assert modes == {"bone-quality": 6, "guarded": 4, "stop-yourself:no-gauges": 1}


def test_the_class_report(
    stations: tuple[Path, Path, Path, dict[str, str]], tmp_path: Path
) -> None:
    a, b, klass, _ = stations
    merged = tmp_path / "class.db"
    assert main(["assess", "--merge", str(a), str(b), "--db", str(merged)]) == 0
    out = tmp_path / "report"
    assert (
        main(["class", "report", "--db", str(merged), "--class", str(klass), "--out", str(out)])
        == 0
    )
    grades = list(csv.DictReader(io.StringIO((out / "grades.csv").read_text())))
    assert [(g["trainee"], g["exercise"]) for g in grades] == [
        (t, e) for t in ("ann", "bo", "'=cmd") for e in ("feel", "demo", "no gauges")
    ]
    ann = {g["exercise"]: g for g in grades if g["trainee"] == "ann"}
    assert (ann["demo"]["attempts"], ann["demo"]["faulted"]) == ("1", "1")  # the link's fault
    assert (ann["no gauges"]["attempts"], ann["no gauges"]["mode"]) == (
        "1",
        "stop-yourself:no-gauges",
    )
    assert float(ann["no gauges"]["best"]) >= 50 and ann["no gauges"]["passed"] == "1"
    assert [g["attempts"] for g in grades if g["exercise"] == "no gauges"] == ["1", "0", "0"]
    feel = {g["trainee"]: g for g in grades if g["exercise"] == "feel"}
    assert (feel["ann"]["best"], feel["ann"]["passed"]) == ("100", "1")
    assert (feel["bo"]["best"], feel["bo"]["passed"]) == ("0", "0")
    demo = [g for g in grades if g["exercise"] == "demo"]
    assert all(g["attempts"] == "1" and float(g["best"]) >= 50 for g in demo)
    conf = list(csv.DictReader(io.StringIO((out / "confusion.csv").read_text())))
    klass_rows = [r for r in conf if r["scope"] == "class"]
    assert sum(int(r["trials"]) for r in klass_rows) == 6
    assert sum(int(r["correct"]) for r in klass_rows) == 4
    assert (out / "dashboard.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (out / "dashboard.pdf").read_bytes()[:5] == b"%PDF-"
    assert (out / "dashboard.png").stat().st_size > 30_000


def test_a_locked_record_is_retried_then_one_error_line(
    stations: tuple[Path, Path, Path, dict[str, str]],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    a, _, _, _ = stations
    merged = tmp_path / "class.db"
    assert main(["assess", "--merge", str(a), "--db", str(merged)]) == 0
    monkeypatch.setattr(record_module, "LOCK_TIMEOUT_S", 0.3)
    holder = sqlite3.connect(merged, isolation_level=None)
    holder.execute("BEGIN EXCLUSIVE")
    try:
        t0 = time.monotonic()
        assert main(["assess", "--merge", str(a), "--db", str(merged)]) == 2
        waited = time.monotonic() - t0
    finally:
        holder.execute("ROLLBACK")
        holder.close()
    err = capsys.readouterr().err
    assert err.startswith("error: --db") and "locked" in err and err.count("\n") == 1
    assert 0.25 <= waited < 5.0


def test_bad_inputs_to_merge_and_report_are_one_error_line(
    stations: tuple[Path, Path, Path, dict[str, str]],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    a, _, klass, _ = stations
    junk = tmp_path / "junk.db"
    junk.write_bytes(b"not a database at all" * 100)
    merged = tmp_path / "class.db"
    for argv in (
        ["assess", "--merge", str(tmp_path / "none.db"), "--db", str(merged)],
        ["assess", "--merge", str(junk), "--db", str(merged)],
        ["assess", "--merge", str(a), "--db", str(merged), "--trainee", "x", "--out", "o"],
        [
            "class",
            "report",
            "--db",
            str(tmp_path / "none.db"),
            "--class",
            str(klass),
            "--out",
            str(tmp_path / "r"),
        ],
        [
            "class",
            "report",
            "--db",
            str(a),
            "--class",
            str(tmp_path / "none.json"),
            "--out",
            str(tmp_path / "r"),
        ],
        ["class", "report", "--db", str(a), "--class", str(junk), "--out", str(tmp_path / "r")],
    ):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert err.startswith("error: ") and err.count("\n") == 1 and "Traceback" not in err
    assert not merged.exists() and not (tmp_path / "r").exists()
    assert junk.read_bytes() == b"not a database at all" * 100
