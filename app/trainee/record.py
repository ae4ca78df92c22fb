"""The trainee record: every assessed session in one SQLite file (stdlib ``sqlite3``).

Schema version :data:`SCHEMA_VERSION` (``PRAGMA user_version``; a version 1 file is migrated
in place when opened to store, :func:`~ctdrill.app.trainee.schema.migrate`):

* ``sessions``: one row per session, keyed by ``session_hash`` (the SHA-256 of the session's
  files, :func:`~ctdrill.app.trainee.session_files.session_hash`): ``trainee`` (NFC,
  case-folded: :func:`check_trainee`), ``expert`` (0/1), ``plan_hash``, ``recorded_at`` (when
  the session ran, UTC ISO-8601), ``stored_at``, ``exam`` (0/1), ``operator``, ``device``,
  ``calibration``, ``planned_depth_mm``, ``max_safe_depth_mm``, how it ran
  (:func:`ctdrill.app.trainee.kinds.session_kind`: ``operator_kind``, ``device_kind``,
  ``mode``, ``complete``, ``outcome``, ``reason``, ``device_fault``), ``program_version``
  (the ctdrill that assessed and stored it), then one column per assessment field
  (:data:`ctdrill.haptics.assessment.ASSESSMENT_FIELDS`, recomputed from the trace);
* ``traces``: the session's time, hand (master), drill and force at :data:`TRACE_RATE_HZ`
  (float32 arrays as blobs), for the window's replay and its expert overlay.

Each session is written in one transaction (``BEGIN IMMEDIATE`` ... ``COMMIT``: its row and its
trace, or neither); SQLite's rollback journal makes that hold through ``kill -9`` and power
loss. The same session stored twice stays one row. A file that is not a ctdrill record, a
corrupt one, one from a newer ctdrill or one locked by another program is refused with an
:class:`RecordError` and left as it was.
"""

from __future__ import annotations

import math
import os
import sqlite3
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from ctdrill import __version__
from ctdrill.app.errors import AppInputError
from ctdrill.app.trainee.kinds import SessionKind, session_kind
from ctdrill.app.trainee.schema import (
    HEAD_COLUMNS,
    SCHEMA,
    SCHEMA_VERSION,
    SESSION_COLUMNS,
    migrate,
    normal_trainee,
)
from ctdrill.app.trainee.session_files import (
    TRACE_ARRAYS,
    TRACE_RATE_HZ,
    SessionEntry,
    read_session,
)
from ctdrill.haptics.assessment import ASSESSMENT_FIELDS, BOOL_FIELDS

#: How long to wait for another program's lock on the file before refusing, s.
LOCK_TIMEOUT_S = 2.0
#: Longest trainee name, characters.
MAX_TRAINEE_CHARS = 100


class RecordError(AppInputError):
    """The trainee record or a session folder cannot be used (the message says why)."""


def check_trainee(trainee: str) -> str:
    """A trainee id: 1 to 100 printable characters, no surrounding spaces; returned in its
    stored form (:func:`normal_trainee`)."""
    trainee = normal_trainee(trainee)
    if not trainee or trainee != trainee.strip() or len(trainee) > MAX_TRAINEE_CHARS:
        raise RecordError(
            f"--trainee {trainee!r}: give 1 to {MAX_TRAINEE_CHARS} characters without "
            "surrounding spaces"
        )
    if not trainee.isprintable():
        raise RecordError(f"--trainee {trainee!r}: use printable characters only")
    return trainee


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")


def _error(path: Path, exc: sqlite3.Error) -> RecordError:
    text = " ".join(str(exc).split())
    if "locked" in text or "busy" in text:
        return RecordError(
            f"--db {path}: the trainee record is locked by another program ({text}); close it "
            "and try again (nothing was written)"
        )
    return RecordError(
        f"--db {path}: not a usable ctdrill trainee record ({text}); the file was left as it "
        "was: check the path, or restore it from a backup"
    )


class TraineeRecord:
    """An open trainee record (use :func:`open_record`)."""

    def __init__(self, path: Path, conn: sqlite3.Connection) -> None:
        self.path = path
        self.conn = conn

    def store(self, entry: SessionEntry, *, trainee: str, expert: bool) -> bool:
        """Store one session in one transaction; False if it was stored already (then the
        row is left as it was). The row's assessment is the one recomputed from the trace
        (``entry.assessment``), its kind :func:`~ctdrill.app.trainee.kinds.session_kind`."""
        s = entry.summary
        a = entry.assessment
        exam = s.get("exam")
        kind: SessionKind = session_kind(s)
        head: dict[str, Any] = {
            **kind.columns(),
            "program_version": __version__,
            "session_hash": entry.session_hash,
            "trainee": normal_trainee(trainee),
            "expert": int(expert),
            "plan_hash": s["plan_sha256"],
            "recorded_at": str(s.get("recorded_at") or _now()),
            "stored_at": _now(),
            "exam": int(bool(isinstance(exam, dict) and exam.get("enabled"))),
            "operator": _text(s.get("operator")),
            "device": _text(s.get("device")),
            "calibration": _text(s.get("calibration")),
            "planned_depth_mm": _real(entry.planned_depth_mm),
            "max_safe_depth_mm": _real(entry.max_safe_depth_mm),
        }
        values = [head[c] for c, _ in HEAD_COLUMNS]
        values += [int(a[f]) if f in BOOL_FIELDS else a[f] for f in ASSESSMENT_FIELDS]
        marks = ", ".join("?" for _ in SESSION_COLUMNS)
        trace = entry.trace
        try:
            with self._transaction() as cur:
                cur.execute(
                    f"INSERT INTO sessions ({', '.join(SESSION_COLUMNS)}) VALUES ({marks}) "
                    "ON CONFLICT (session_hash) DO NOTHING",
                    values,
                )
                if cur.rowcount == 0:
                    return False
                self._store_trace(cur, entry.session_hash, trace)
        except sqlite3.Error as exc:
            raise _error(self.path, exc) from exc
        return True

    def _store_trace(self, cur: sqlite3.Cursor, key: str, trace: Mapping[str, np.ndarray]) -> None:
        """The session's replay trace (inside the session's transaction)."""
        arrays = [np.asarray(trace[a], dtype="<f4").tobytes() for a in TRACE_ARRAYS]
        cur.execute(
            f"INSERT INTO traces (session_hash, rate_hz, samples, {', '.join(TRACE_ARRAYS)}) "
            "VALUES (?, ?, ?, ?, ?, ?, ?)",
            [key, TRACE_RATE_HZ, len(trace["time_s"]), *arrays],
        )

    @contextmanager
    def _transaction(self) -> Iterator[sqlite3.Cursor]:
        cur = self.conn.cursor()
        cur.execute("BEGIN IMMEDIATE")
        try:
            yield cur
        except BaseException:
            self.conn.rollback()
            raise
        self.conn.commit()

    def sessions(
        self,
        *,
        trainee: str | None = None,
        plan_hash: str | None = None,
        expert: bool | None = None,
        mode: str | None = None,
    ) -> list[dict[str, Any]]:
        """Rows (column -> value, booleans as bool, null where unknown) in time order,
        filtered (``trainee`` compared in its stored form)."""
        where: list[str] = []
        args: list[object] = []
        if trainee is not None:
            trainee = normal_trainee(trainee)
        for column, value in (("trainee", trainee), ("plan_hash", plan_hash), ("mode", mode)):
            if value is not None:
                where.append(f"{column} = ?")
                args.append(value)
        if expert is not None:
            where.append("expert = ?")
            args.append(int(expert))
        sql = f"SELECT {', '.join(SESSION_COLUMNS)} FROM sessions"
        if where:
            sql += " WHERE " + " AND ".join(where)
        try:
            rows = self.conn.execute(sql + " ORDER BY recorded_at, rowid", args).fetchall()
        except sqlite3.Error as exc:
            raise _error(self.path, exc) from exc
        out = []
        for row in rows:
            item = dict(zip(SESSION_COLUMNS, row, strict=True))
            for name in ("expert", "exam", "complete", "device_fault", *BOOL_FIELDS):
                if item[name] is not None:
                    item[name] = bool(item[name])
            out.append(item)
        return out

    def trace(self, key: str) -> dict[str, np.ndarray] | None:
        """A session's replay trace (None if it has none)."""
        try:
            row = self.conn.execute(
                f"SELECT {', '.join(TRACE_ARRAYS)} FROM traces WHERE session_hash = ?", (key,)
            ).fetchone()
        except sqlite3.Error as exc:
            raise _error(self.path, exc) from exc
        if row is None:
            return None
        return {
            a: np.frombuffer(b, dtype="<f4").copy() for a, b in zip(TRACE_ARRAYS, row, strict=True)
        }

    def close(self) -> None:
        """Close the file."""
        self.conn.close()


def _text(value: object) -> str | None:
    return None if value is None else str(value)


def _real(value: object) -> float | None:
    if isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value):
        return float(value)
    return None


def _tables(conn: sqlite3.Connection) -> set[str]:
    rows = conn.execute("SELECT name FROM sqlite_master WHERE type = 'table'").fetchall()
    return {str(r[0]) for r in rows}


def open_record(path: Path, *, create: bool) -> TraineeRecord:
    """Open the trainee record at ``path`` (``create``: a missing or empty file becomes a new
    record; otherwise it must exist).

    Raises
    ------
    RecordError
        Missing (without ``create``), not SQLite, corrupt, of a newer schema, another
        program's database, or locked beyond :data:`LOCK_TIMEOUT_S`. The file is not changed.
    """
    if not path.exists():
        if not create:
            raise RecordError(f"--db {path}: no such trainee record; record a session first")
        if not path.parent.is_dir():
            raise RecordError(f"--db {path}: the folder {path.parent} does not exist")
    elif not path.is_file():
        raise RecordError(f"--db {path}: not a regular file")
    try:
        conn = sqlite3.connect(
            os.fspath(path), timeout=LOCK_TIMEOUT_S, isolation_level=None, check_same_thread=False
        )
    except sqlite3.Error as exc:
        raise _error(path, exc) from exc
    try:
        version = int(conn.execute("PRAGMA user_version").fetchone()[0])
        tables = _tables(conn)
        if version > SCHEMA_VERSION:
            raise RecordError(
                f"--db {path}: a trainee record of schema {version}, newer than this ctdrill "
                f"reads ({SCHEMA_VERSION}); update ctdrill"
            )
        if version in (1, SCHEMA_VERSION):
            if not {"sessions", "traces"} <= tables:
                raise RecordError(f"--db {path}: its sessions or traces table is missing")
            check = " ".join(str(conn.execute("PRAGMA quick_check").fetchone()[0]).split())
            if check != "ok":
                raise RecordError(
                    f"--db {path}: the trainee record is damaged ({check}); the file was left "
                    "as it was: restore it from a backup"
                )
            if version == 1:
                migrate(conn)
        elif tables:
            raise RecordError(
                f"--db {path}: an SQLite database that is not a ctdrill trainee record (tables "
                f"{', '.join(sorted(tables))}); name another file"
            )
        elif not create:
            raise RecordError(f"--db {path}: an empty trainee record; record a session first")
        else:
            conn.execute("BEGIN IMMEDIATE")
            if not _tables(conn):
                for statement in SCHEMA:
                    conn.execute(statement)
                conn.execute(f"PRAGMA user_version = {SCHEMA_VERSION}")
            conn.execute("COMMIT")
    except RecordError:
        conn.close()
        raise
    except sqlite3.Error as exc:
        conn.close()
        raise _error(path, exc) from exc
    return TraineeRecord(path, conn)


def record_sessions(
    path: Path, folders: Sequence[Path], *, trainee: str, expert: bool
) -> list[tuple[SessionEntry, bool]]:
    """Read and check every folder, then store each session in its own transaction.

    Returns ``(entry, stored)`` per folder (``stored`` False: it was there already).
    """
    trainee = check_trainee(trainee)
    entries = [read_session(f) for f in folders]
    record = open_record(path, create=True)
    try:
        return [(e, record.store(e, trainee=trainee, expert=expert)) for e in entries]
    finally:
        record.close()


#: The record's error for an SQLite failure on ``path`` (locked, damaged ...), for the
#: modules that write to it (:mod:`ctdrill.app.trainee.merge`).
record_error = _error
