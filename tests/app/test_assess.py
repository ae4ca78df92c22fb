"""``ctdrill assess``: the SQLite trainee record, the learning curve, locks, damage, kill -9."""

from __future__ import annotations

import csv
import json
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from ctdrill.app.cli import main
from ctdrill.app.trainee import record as record_module
from ctdrill.app.trainee.curve import CURVE_COLUMNS, percentile
from ctdrill.app.trainee.record import SCHEMA_VERSION, open_record, read_session
from ctdrill.haptics.assessment import ASSESSMENT_FIELDS
from tests.app.trainee_sessions import rewrite

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "assets" / "demo"


@pytest.fixture(scope="module")
def real_session(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A real rehearsal of the demo (20 N to the margin's stop)."""
    out = tmp_path_factory.mktemp("sessions") / "real"
    argv = ["rehearse", "--dicom", str(DEMO / "ct"), "--plan", str(DEMO / "plan.json")]
    assert main([*argv, "--out", str(out), "--operator", "push:20", "--duration-s", "1.6"]) == 0
    return out


def _variant(real: Path, dest: Path, when: str, **changes: Any) -> Path:
    """Another session made from the real one (its trace changed: ``depth_scale``,
    ``rest_rows``...; the assessment recomputed), recorded at ``when``."""
    return rewrite(real, dest, when, **changes)


def _assess(*args: str | Path) -> int:
    return main(["assess", *(str(a) for a in args)])


def _rows(db: Path) -> list[tuple[Any, ...]]:
    with sqlite3.connect(db) as conn:
        return conn.execute("SELECT * FROM sessions ORDER BY session_hash").fetchall()


def test_sessions_are_stored_once_each_with_every_field(real_session: Path, tmp_path: Path) -> None:
    db = tmp_path / "record.sqlite"
    assert _assess(real_session, real_session, "--db", db, "--trainee", "alice") == 0
    assert _assess(real_session, "--db", db, "--trainee", "alice") == 0
    with sqlite3.connect(db) as conn:
        assert conn.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION
        columns = [r[1] for r in conn.execute("PRAGMA table_info(sessions)")]
        row = conn.execute(
            f"SELECT trainee, expert, plan_hash, recorded_at, {', '.join(ASSESSMENT_FIELDS)} "
            "FROM sessions"
        ).fetchall()
        traces = conn.execute("SELECT samples FROM traces").fetchall()
    assert {"trainee", "expert", "plan_hash", "recorded_at", *ASSESSMENT_FIELDS} <= set(columns)
    summary = json.loads((real_session / "summary.json").read_text())
    assert len(row) == 1 and len(traces) == 1
    trainee, expert, plan, recorded, *values = row[0]
    assert (trainee, expert, plan, recorded) == (
        "alice",
        0,
        summary["plan_sha256"],
        summary["recorded_at"],
    )
    a = summary["assessment"]
    assert values == [int(a[f]) if isinstance(a[f], bool) else a[f] for f in ASSESSMENT_FIELDS]
    assert traces[0][0] == pytest.approx(1600 / 10, abs=2)  # 1.6 s at 100 Hz


def test_learning_curve_and_percentiles_against_experts(real_session: Path, tmp_path: Path) -> None:
    db = tmp_path / "record.sqlite"
    t = "2030-01-0{}T10:00:00+00:00"
    late = _variant(real_session, tmp_path / "late", t.format(3), depth_scale=0.98)
    early = _variant(real_session, tmp_path / "early", t.format(1), depth_scale=1.25)
    experts = [
        _variant(
            real_session,
            tmp_path / f"expert{i}",
            t.format(5 + i),
            depth_scale=1.0 - 0.01 * i,
            rest_rows=1,
        )
        for i in range(3)
    ]
    assert _assess(late, early, "--db", db, "--trainee", "bob") == 0
    assert _assess(*experts, "--db", db, "--trainee", "dr-e", "--expert") == 0
    out = tmp_path / "curve"
    assert _assess("--db", db, "--trainee", "bob", "--out", out) == 0
    with (out / "learning_curve.csv").open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert tuple(rows[0]) == CURVE_COLUMNS
    assert [r["recorded_at"] for r in rows] == [t.format(1), t.format(3)]  # time order
    assert [r["breach"] for r in rows] == ["1", "0"]
    scores = [float(r["score"]) for r in rows]
    assert scores[0] < 45.0 <= 50.0 <= scores[1]
    expert_scores = [
        json.loads((e / "summary.json").read_text())["assessment"]["score"] for e in experts
    ]
    for r, s in zip(rows, scores, strict=True):
        assert r["expert_sessions"] == "3"
        assert float(r["score_expert_percentile"]) == percentile(s, expert_scores)
    with (out / "percentiles.csv").open(newline="") as fh:
        pct = {r["metric"]: r for r in csv.DictReader(fh)}
    assert set(pct) == {"score", *ASSESSMENT_FIELDS[:-1]}
    assert float(pct["overshoot_mm"]["percentile"]) == 50.0  # all equal (0): ties count half
    assert (out / "learning_curve.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert percentile(2.0, [1.0, 2.0, 3.0, 4.0]) == 37.5 and percentile(1.0, []) is None


def _one_error(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: "), err
    return err[0]


def test_bad_input_is_one_error_line_and_nothing_is_lost(
    real_session: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: Any
) -> None:
    db = tmp_path / "record.sqlite"
    assert _assess(real_session, "--db", db, "--trainee", "carol") == 0
    before = _rows(db)
    capsys.readouterr()
    # a session folder without an assessment: nothing stored, the record as it was
    old = _variant(real_session, tmp_path / "old", "2030-01-01T00:00:00+00:00", rest_rows=2)
    summary = json.loads((old / "summary.json").read_text())
    del summary["assessment"]
    (old / "summary.json").write_text(json.dumps(summary))
    other = _variant(real_session, tmp_path / "other", "2030-01-02T00:00:00+00:00", rest_rows=3)
    assert _assess(other, old, "--db", db, "--trainee", "carol") == 2
    assert "no assessment" in _one_error(capsys) and _rows(db) == before
    # locked by another program: refused once the lock timeout it gives SQLite has passed
    # (the timeout is read from the connection made, not timed: a loaded host is slower)
    monkeypatch.setattr(record_module, "LOCK_TIMEOUT_S", 0.2)
    holder = sqlite3.connect(db, isolation_level=None)
    holder.execute("BEGIN EXCLUSIVE")
    timeouts: list[float] = []
    connect = sqlite3.connect

    def recording_connect(*args: Any, **kwargs: Any) -> sqlite3.Connection:
        timeouts.append(kwargs.get("timeout", 5.0))  # 5.0: sqlite3's own default
        return connect(*args, **kwargs)

    monkeypatch.setattr(record_module.sqlite3, "connect", recording_connect)
    try:
        assert _assess(other, "--db", db, "--trainee", "carol") == 2
        assert timeouts and set(timeouts) == {0.2}
        assert "locked" in _one_error(capsys)
    finally:
        holder.execute("ROLLBACK")
        holder.close()
    assert _rows(db) == before
    # not a database, a damaged one, another program's: refused, the bytes untouched
    junk = tmp_path / "junk.sqlite"
    junk.write_bytes(b"this is not a database" * 100)
    foreign = tmp_path / "foreign.sqlite"
    with sqlite3.connect(foreign) as conn:
        conn.execute("CREATE TABLE notes (x)")
    damaged = tmp_path / "damaged.sqlite"
    data = bytearray(db.read_bytes())
    page = 4096
    data[2 * page : 3 * page] = b"\xa5" * page  # a b-tree page overwritten
    damaged.write_bytes(bytes(data))
    for bad, why in ((junk, "not a usable"), (foreign, "not a ctdrill"), (damaged, "")):
        blob = bad.read_bytes()
        assert _assess(other, "--db", bad, "--trainee", "carol") == 2
        assert why in _one_error(capsys)
        assert bad.read_bytes() == blob
    assert (
        _assess("--db", tmp_path / "none.sqlite", "--trainee", "carol", "--out", tmp_path / "o")
        == 2
    )
    assert "no such trainee record" in _one_error(capsys)
    assert _assess("--db", db, "--trainee", "nobody", "--out", tmp_path / "o") == 2
    assert "no session of this trainee" in _one_error(capsys)
    assert _assess(real_session, "--db", db, "--trainee", " x") == 2
    assert "--trainee" in _one_error(capsys)


KILLED_MID_TRANSACTION = """
import pathlib, sys, threading
from ctdrill.app.trainee import record
store_trace = record.TraineeRecord._store_trace

def stall(self, cur, key, trace):
    store_trace(self, cur, key, trace)  # the row and its trace written, not committed
    pathlib.Path(sys.argv[1]).write_text("in the transaction")
    threading.Event().wait()  # until killed, however long the test takes to do it

record.TraineeRecord._store_trace = stall
from ctdrill.app.cli import main
sys.exit(main(sys.argv[2:]))
"""


@pytest.mark.timeout(120)
def test_the_record_survives_kill_9_mid_transaction(real_session: Path, tmp_path: Path) -> None:
    db = tmp_path / "record.sqlite"
    assert _assess(real_session, "--db", db, "--trainee", "dave") == 0
    before = _rows(db)
    new = _variant(real_session, tmp_path / "new", "2030-02-01T00:00:00+00:00", rest_rows=4)
    marker = tmp_path / "marker"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-c",
            KILLED_MID_TRANSACTION,
            str(marker),
            "assess",
            str(new),
            "--db",
            str(db),
            "--trainee",
            "dave",
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    try:
        deadline = time.monotonic() + 60.0
        while not marker.exists():
            assert proc.poll() is None, proc.stderr.read() if proc.stderr else ""
            assert time.monotonic() < deadline
            time.sleep(0.02)
        os.kill(proc.pid, signal.SIGKILL)
        assert proc.wait(timeout=30) == -signal.SIGKILL
    finally:
        if proc.poll() is None:
            proc.kill()
        if proc.stderr is not None:
            proc.stderr.close()
    assert Path(f"{db}-journal").exists()  # the hot journal the next opener rolls back
    record = open_record(db, create=False)  # checks the file (quick_check)
    try:
        new_hash = read_session(new).session_hash
        assert [s["session_hash"] for s in record.sessions()] != [] and all(
            s["session_hash"] != new_hash for s in record.sessions()
        )
        assert record.trace(new_hash) is None
    finally:
        record.close()
    assert _rows(db) == before  # the old rows intact, the new session absent
    with sqlite3.connect(db) as conn:
        assert conn.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
    assert _assess(new, "--db", db, "--trainee", "dave") == 0  # and it can be stored whole
    after = _rows(db)
    assert len(after) == len(before) + 1 and set(before) <= set(after)
