"""The trainee record's answers to blind trials, and the confusion matrices they give.

Table ``answers`` (created on first use beside ``sessions`` and ``traces``): one row per blind
session answered, keyed by its ``session_hash`` (a ``sessions`` row): ``exercise``,
``exercise_id``, ``trial``, ``answer`` (what the trainee named), ``truth`` (the trial's class,
from its sealed key) and ``answered_at`` (UTC). A session is answered once: the first answer
stands. The confusion matrix counts answers by (truth, answer), for one trainee (the record's
view ``confusion``) or a class.
"""

from __future__ import annotations

import sqlite3
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any

from ctdrill.app.errors import AppInputError
from ctdrill.app.exercise.bone_quality import TRIAL_CLASSES

ANSWER_COLUMNS = (
    "session_hash",
    "exercise",
    "exercise_id",
    "trial",
    "answer",
    "truth",
    "answered_at",
)
ANSWERS_SCHEMA = (
    "CREATE TABLE IF NOT EXISTS answers ("
    "session_hash TEXT PRIMARY KEY REFERENCES sessions (session_hash), "
    "exercise TEXT NOT NULL, exercise_id TEXT NOT NULL, trial TEXT NOT NULL, "
    "answer TEXT NOT NULL, truth TEXT NOT NULL, answered_at TEXT NOT NULL)"
)


class AnswerError(AppInputError):
    """An answer that cannot be recorded (the message says why)."""


def check_answer(text: str) -> str:
    """A named class: ``D1`` .. ``D4`` (any case, surrounding spaces ignored)."""
    name = str(text).strip().upper()
    if name not in TRIAL_CLASSES:
        raise AnswerError(
            f"--answer {text!r}: name the bone's class, one of {', '.join(TRIAL_CLASSES)}"
        )
    return name


@dataclass(frozen=True)
class Answer:
    """A trainee's answer to one blind session."""

    session_hash: str
    exercise: str
    exercise_id: str
    trial: str
    answer: str
    truth: str

    @property
    def correct(self) -> bool:
        """The class named is the trial's."""
        return self.answer == self.truth


#: The record's confusion matrix per trainee: answers counted by (trainee, exercise, truth,
#: answer) (a class's is its trainees' together: ``ctdrill class report``).
CONFUSION_VIEW = (
    "CREATE VIEW IF NOT EXISTS confusion AS SELECT s.trainee AS trainee, a.exercise AS "
    "exercise, a.truth AS truth, a.answer AS answer, COUNT(*) AS answers FROM answers a JOIN "
    "sessions s USING (session_hash) GROUP BY s.trainee, a.exercise, a.truth, a.answer"
)


def ensure_answers_table(conn: sqlite3.Connection) -> None:
    """Create ``answers`` and the ``confusion`` view when the record has none yet (its own
    transaction)."""
    conn.execute("BEGIN IMMEDIATE")
    try:
        conn.execute(ANSWERS_SCHEMA)
        conn.execute(CONFUSION_VIEW)
    except BaseException:
        conn.rollback()
        raise
    conn.execute("COMMIT")


def has_answers_table(conn: sqlite3.Connection) -> bool:
    """True when the record has an ``answers`` table."""
    row = conn.execute(
        "SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = 'answers'"
    ).fetchone()
    return row is not None


def store_answer(conn: sqlite3.Connection, answer: Answer) -> str | None:
    """Store ``answer`` in one transaction; None when stored (or stored before, the same),
    else the answer the session already holds (then nothing changes)."""
    conn.execute("BEGIN IMMEDIATE")
    try:
        row = conn.execute(
            "SELECT answer FROM answers WHERE session_hash = ?", (answer.session_hash,)
        ).fetchone()
        if row is None:
            conn.execute(
                f"INSERT INTO answers ({', '.join(ANSWER_COLUMNS)}) VALUES (?, ?, ?, ?, ?, ?, ?)",
                (
                    answer.session_hash,
                    answer.exercise,
                    answer.exercise_id,
                    answer.trial,
                    answer.answer,
                    answer.truth,
                    datetime.now(UTC).isoformat(timespec="seconds"),
                ),
            )
    except BaseException:
        conn.rollback()
        raise
    conn.execute("COMMIT")
    if row is None or str(row[0]) == answer.answer:
        return None
    return str(row[0])


def answers(conn: sqlite3.Connection, *, exercise: str | None = None) -> list[dict[str, Any]]:
    """Every answer with its session's trainee and time, in time order."""
    if not has_answers_table(conn):
        return []
    sql = (
        "SELECT s.trainee, s.recorded_at, a.session_hash, a.exercise, a.exercise_id, a.trial, "
        "a.answer, a.truth FROM answers a JOIN sessions s USING (session_hash)"
    )
    args: list[object] = []
    if exercise is not None:
        sql += " WHERE a.exercise = ?"
        args.append(exercise)
    rows = conn.execute(sql + " ORDER BY s.recorded_at, a.rowid", args).fetchall()
    keys = ("trainee", "recorded_at", "session_hash", "exercise", "exercise_id", "trial")
    return [dict(zip((*keys, "answer", "truth"), r, strict=True)) for r in rows]


def confusion(
    rows: Iterable[Mapping[str, Any]], classes: Sequence[str] = TRIAL_CLASSES
) -> dict[tuple[str, str], int]:
    """Counts of (truth, answer) over ``rows`` (every pair of ``classes``, zeros included)."""
    out = {(t, a): 0 for t in classes for a in classes}
    for r in rows:
        key = (str(r["truth"]), str(r["answer"]))
        if key in out:
            out[key] += 1
    return out


def answer_sessions(
    path: Any, folders: Sequence[Any], named: Sequence[str], *, trainee: str, expert: bool = False
) -> list[tuple[Any, bool, Answer, str | None]]:
    """Store each blind session (as ``ctdrill assess`` does) and the class the trainee named
    for it, ``named[k]`` for ``folders[k]``. Every folder, key and answer is read and checked
    before the first write.

    Returns ``(entry, stored, answer, earlier)`` per folder: ``stored`` False when the session
    was in the record already, ``earlier`` the answer it held when that differs (it stands).

    Raises
    ------
    AnswerError
        Not one answer per session, or a class that is not D1-D4.
    TrialError, SealError, RecordError
        A session that is not a blind trial's, a key that does not open, an unusable record.
    """
    from ctdrill.app.trainee.session_files import read_session

    if len(named) != len(folders):
        raise AnswerError(
            f"--answer given {len(named)} times for {len(folders)} sessions: name the class of "
            "each session, in the order the sessions are given"
        )
    check_trainee_id(trainee)
    classes = [check_answer(a) for a in named]
    return answer_entries(
        path, [read_session(f) for f in folders], classes, trainee=trainee, expert=expert
    )


def check_trainee_id(trainee: str) -> str:
    """The record's trainee id (:func:`ctdrill.app.trainee.record.check_trainee`)."""
    from ctdrill.app.trainee.record import check_trainee

    return check_trainee(trainee)


def answer_entries(
    path: Any, entries: Sequence[Any], named: Sequence[str], *, trainee: str, expert: bool = False
) -> list[tuple[Any, bool, Answer, str | None]]:
    """:func:`answer_sessions` of sessions already read (the window's, from memory): each
    key opened and every answer checked before the first write."""
    from ctdrill.app.exercise.trials import trial_key
    from ctdrill.app.trainee.record import open_record, record_error

    trainee = check_trainee_id(trainee)
    classes = [check_answer(a) for a in named]
    keys = [trial_key(e.summary, where=str(e.folder)) for e in entries]
    record = open_record(path, create=True)
    out: list[tuple[Any, bool, Answer, str | None]] = []
    try:
        try:
            ensure_answers_table(record.conn)
        except sqlite3.Error as exc:
            raise record_error(record.path, exc) from exc
        for entry, (card, truth), name in zip(entries, keys, classes, strict=True):
            stored = record.store(entry, trainee=trainee, expert=expert)
            answer = Answer(
                entry.session_hash, card.exercise, card.exercise_id, card.trial, name, truth
            )
            try:
                earlier = store_answer(record.conn, answer)
            except sqlite3.Error as exc:
                raise record_error(record.path, exc) from exc
            out.append((entry, stored, answer, earlier))
    finally:
        record.close()
    return out
