"""The trainee record's SQLite schema (version :data:`SCHEMA_VERSION`) and the migration of an
older record (:func:`migrate`); :mod:`ctdrill.app.trainee.record` opens and writes it.
"""

from __future__ import annotations

import sqlite3
import unicodedata

from ctdrill.app.trainee.kinds import session_kind
from ctdrill.app.trainee.session_files import TRACE_ARRAYS
from ctdrill.haptics.assessment import ASSESSMENT_FIELDS, BOOL_FIELDS, INT_FIELDS, NULLABLE_FIELDS

SCHEMA_VERSION = 2
#: The session columns before the assessment's, with their SQL types.
HEAD_COLUMNS = (
    ("session_hash", "TEXT PRIMARY KEY"),
    ("trainee", "TEXT NOT NULL"),
    ("expert", "INTEGER NOT NULL CHECK (expert IN (0, 1))"),
    ("plan_hash", "TEXT NOT NULL"),
    ("recorded_at", "TEXT NOT NULL"),
    ("stored_at", "TEXT NOT NULL"),
    ("exam", "INTEGER NOT NULL CHECK (exam IN (0, 1))"),
    ("operator", "TEXT"),
    ("device", "TEXT"),
    ("calibration", "TEXT"),
    ("planned_depth_mm", "REAL"),
    ("max_safe_depth_mm", "REAL"),
    ("operator_kind", "TEXT"),
    ("device_kind", "TEXT"),
    ("mode", "TEXT"),
    ("complete", "INTEGER CHECK (complete IN (0, 1))"),
    ("outcome", "TEXT"),
    ("reason", "TEXT"),
    ("device_fault", "INTEGER NOT NULL DEFAULT 0 CHECK (device_fault IN (0, 1))"),
    ("program_version", "TEXT"),
)
#: Columns a version 1 record lacks, added by :func:`_migrate` (its rows: null, or derived).
_V1_HEAD = (
    "session_hash",
    "trainee",
    "expert",
    "plan_hash",
    "recorded_at",
    "stored_at",
    "exam",
    "operator",
    "device",
    "calibration",
    "planned_depth_mm",
    "max_safe_depth_mm",
)


def _field_type(name: str, *, added: bool = False) -> str:
    """A field's SQL type; ``added`` (migrating): nullable, old rows have no value."""
    if name in BOOL_FIELDS:
        return f"INTEGER{'' if added else ' NOT NULL'} CHECK ({name} IN (0, 1))"
    if name in INT_FIELDS:
        return "INTEGER" if added else "INTEGER NOT NULL"
    return "REAL" if added or name in NULLABLE_FIELDS else "REAL NOT NULL"


#: The assessment fields of a version 1 record.
_V1_FIELDS = (*ASSESSMENT_FIELDS[: ASSESSMENT_FIELDS.index("peak_wall_force_n") + 1], "score")


SESSION_COLUMNS = tuple(c for c, _ in HEAD_COLUMNS) + ASSESSMENT_FIELDS
SCHEMA = (
    "CREATE TABLE sessions ("
    + ", ".join(
        [f"{c} {t}" for c, t in HEAD_COLUMNS] + [f"{f} {_field_type(f)}" for f in ASSESSMENT_FIELDS]
    )
    + ")",
    "CREATE INDEX sessions_by_trainee ON sessions (trainee, recorded_at)",
    "CREATE INDEX sessions_by_plan ON sessions (plan_hash, expert)",
    "CREATE INDEX sessions_by_mode ON sessions (plan_hash, mode, expert)",
    "CREATE TABLE traces (session_hash TEXT PRIMARY KEY REFERENCES sessions (session_hash), "
    "rate_hz REAL NOT NULL, samples INTEGER NOT NULL, "
    + ", ".join(f"{a} BLOB NOT NULL" for a in TRACE_ARRAYS)
    + ")",
)


def normal_trainee(trainee: str) -> str:
    """The stored form of a trainee id: Unicode NFC, case-folded ("Zoë" typed as one
    code point or as "e" and a combining diaeresis, in any case, is one trainee)."""
    return unicodedata.normalize("NFC", unicodedata.normalize("NFC", trainee).casefold())


def migrate(conn: sqlite3.Connection) -> None:
    """Version 1 -> 2 in one transaction: add the columns of how a session ran and the
    assessment fields added since (old rows: ``mode`` from ``exam``, ``operator_kind`` and
    ``device_kind`` from the operator and device texts, the rest null; ``device_fault`` 0),
    and store every trainee id in its normal form."""
    conn.execute("BEGIN IMMEDIATE")
    try:
        if int(conn.execute("PRAGMA user_version").fetchone()[0]) != 1:
            conn.execute("ROLLBACK")
            return
        have = {str(r[1]) for r in conn.execute("PRAGMA table_info(sessions)").fetchall()}
        for column, sql_type in HEAD_COLUMNS:
            if column not in have and column not in _V1_HEAD:
                conn.execute(f"ALTER TABLE sessions ADD COLUMN {column} {sql_type}")
        for name in ASSESSMENT_FIELDS:
            if name not in have and name not in _V1_FIELDS:
                conn.execute(
                    f"ALTER TABLE sessions ADD COLUMN {name} {_field_type(name, added=True)}"
                )
        rows = conn.execute("SELECT session_hash, trainee, exam, operator, device FROM sessions")
        for key, trainee, exam, operator, device in rows.fetchall():
            kind = session_kind(
                {"operator": operator, "device": device, "exam": {"enabled": bool(exam)}}
            )
            conn.execute(
                "UPDATE sessions SET trainee = ?, mode = ?, operator_kind = ?, device_kind = ? "
                "WHERE session_hash = ?",
                (
                    normal_trainee(str(trainee)),
                    kind.mode,
                    kind.operator_kind,
                    kind.device_kind,
                    key,
                ),
            )
        conn.execute(
            "CREATE INDEX IF NOT EXISTS sessions_by_mode ON sessions (plan_hash, mode, expert)"
        )
        conn.execute(f"PRAGMA user_version = {SCHEMA_VERSION}")
        conn.execute("COMMIT")
    except BaseException:
        conn.execute("ROLLBACK")
        raise
