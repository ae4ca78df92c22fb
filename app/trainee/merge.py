"""Merge station records into one (``ctdrill assess --merge A.db B.db --db CLASS.db``).

Every session is keyed by its content hash (``session_hash``), so a merge copies the sessions
the class record lacks, with their traces and answers, and skips those it holds: merging the
same station twice, or a station's record into itself, changes nothing. A session stored under
another trainee on another station keeps the class record's row and is counted as a conflict.
Each station is merged in one transaction (all its new rows, or none). The columns copied are
those both records have.
"""

from __future__ import annotations

import os
import sqlite3
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from ctdrill.app.trainee.answers import ensure_answers_table, has_answers_table
from ctdrill.app.trainee.record import RecordError, open_record, record_error


@dataclass(frozen=True)
class MergeCount:
    """What one station's merge did."""

    source: Path
    sessions: int
    added: int
    answers_added: int
    conflicts: int


def _columns(conn: sqlite3.Connection, schema: str, table: str) -> list[str]:
    rows = conn.execute(f"PRAGMA {schema}.table_info({table})").fetchall()
    return [str(r[1]) for r in rows]


def _copy(conn: sqlite3.Connection, table: str) -> int:
    """Rows of ``src.table`` whose session the class record lacks, copied; how many."""
    theirs = _columns(conn, "src", table)
    cols = ", ".join(c for c in _columns(conn, "main", table) if c in theirs)
    cur = conn.execute(
        f"INSERT INTO main.{table} ({cols}) SELECT {cols} FROM src.{table} "
        f"WHERE session_hash NOT IN (SELECT session_hash FROM main.{table})"
    )
    return int(cur.rowcount)


def merge_records(dest: Path, sources: Sequence[Path]) -> list[MergeCount]:
    """Merge each of ``sources`` into ``dest`` (created when missing): module docstring.

    Raises
    ------
    RecordError
        A source or the destination that is not a usable trainee record, or locked beyond
        the record's lock timeout; stations merged before it stay merged.
    """
    for src in sources:  # every station checked before the first write
        open_record(src, create=False).close()
    record = open_record(dest, create=True)
    conn = record.conn
    out: list[MergeCount] = []
    try:
        ensure_answers_table(conn)
        for src in sources:
            if os.path.realpath(src) == os.path.realpath(dest):
                total = int(conn.execute("SELECT COUNT(*) FROM sessions").fetchone()[0])
                out.append(MergeCount(src, total, 0, 0, 0))
                continue
            conn.execute("ATTACH DATABASE ? AS src", (os.fspath(src),))
            try:
                conn.execute("BEGIN IMMEDIATE")
                try:
                    total = int(conn.execute("SELECT COUNT(*) FROM src.sessions").fetchone()[0])
                    conflicts = int(
                        conn.execute(
                            "SELECT COUNT(*) FROM src.sessions s JOIN main.sessions m "
                            "USING (session_hash) WHERE s.trainee != m.trainee"
                        ).fetchone()[0]
                    )
                    added = _copy(conn, "sessions")
                    _copy(conn, "traces")
                    got = _copy(conn, "answers") if _src_has_answers(conn) else 0
                except BaseException:
                    conn.rollback()
                    raise
                conn.execute("COMMIT")
            finally:
                conn.execute("DETACH DATABASE src")
            out.append(MergeCount(src, total, added, got, conflicts))
    except sqlite3.Error as exc:
        raise record_error(dest, exc) from exc
    finally:
        record.close()
    return out


def _src_has_answers(conn: sqlite3.Connection) -> bool:
    row = conn.execute(
        "SELECT 1 FROM src.sqlite_master WHERE type = 'table' AND name = 'answers'"
    ).fetchone()
    return row is not None


__all__ = ["MergeCount", "RecordError", "has_answers_table", "merge_records"]
