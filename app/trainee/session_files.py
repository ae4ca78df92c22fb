"""A rehearsal's folder as the trainee record reads it: ``session.csv`` (the trace),
``table.json`` (what it was assessed against: :mod:`ctdrill.app.trainee.session_table`), the
window's ``display.csv`` when there is one, and ``summary.json``; the session's content hash.

The assessment stored is recomputed from the trace and the table, never read from
``summary.json``: a summary whose ``assessment`` (or plan hash, planned or max safe depth)
disagrees with the trace is refused, naming the first field that differs. The content hash
covers the trace and the table (not the summary's bytes: the same session re-saved with a
space added is the same session).

A drill sequence's folder (``ctdrill rehearse`` of a plan with ``drills``: ``drill_k/`` per
drill and a listing ``summary.json``) is one session: each drill's assessment recomputed from
its own folder, combined (:func:`ctdrill.haptics.assessment.combine_assessments`), and as its
trace the drills' ``session.csv`` one after the other; its hash covers every drill's files.
A drill's own folder is that drill alone.
"""

from __future__ import annotations

import csv
import hashlib
import io
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ctdrill.app.trainee.session_table import (
    DISPLAY_FILE,
    TABLE_FILE,
    SessionTraceError,
    first_disagreement,
    read_table,
    recompute,
)
from ctdrill.haptics.assessment import (
    ASSESSMENT_FIELDS,
    BOOL_FIELDS,
    INT_FIELDS,
    NULLABLE_FIELDS,
    combine_assessments,
)
from ctdrill.safeio import loads_json, read_bytes_bounded

#: The replay trace is kept at this rate, Hz.
TRACE_RATE_HZ = 100.0
#: Its arrays (float32): session time, hand (master) and drill depth, device force.
TRACE_ARRAYS = ("time_s", "master_mm", "drill_mm", "force_n")
#: Largest ``session.csv`` read, bytes (an hour at 1 kHz is about 150 MB).
MAX_SESSION_CSV_BYTES = 256 * 1024 * 1024
#: Largest ``summary.json`` read, bytes.
MAX_SUMMARY_BYTES = 16 * 1024 * 1024


class SessionFileError(SessionTraceError):
    """A session folder that cannot be recorded (the message names the file and why)."""


@dataclass(frozen=True, eq=False)
class SessionEntry:
    """One session folder, read and checked, ready to store: ``assessment`` is the one
    recomputed from its trace; the depths are its table's."""

    folder: Path
    session_hash: str
    summary: dict[str, Any]
    trace: dict[str, np.ndarray]
    assessment: dict[str, Any]
    planned_depth_mm: float
    max_safe_depth_mm: float | None


@dataclass(frozen=True)
class SessionFiles:
    """The bytes of one session's files (``display`` None: no window display log)."""

    summary: bytes
    csv: bytes
    table: bytes
    display: bytes | None = None


def session_hash(parts: list[tuple[str, bytes]]) -> str:
    """The session's content hash: SHA-256 of its named trace and table files."""
    h = hashlib.sha256(b"ctdrill-session/2\0")
    for name, data in parts:
        h.update(f"{name}\0{len(data)}\0".encode() + data)
    return h.hexdigest()


def _parts(files: SessionFiles, prefix: str = "") -> list[tuple[str, bytes]]:
    out = [(prefix + "session.csv", files.csv), (prefix + TABLE_FILE, files.table)]
    if files.display is not None:
        out.append((prefix + DISPLAY_FILE, files.display))
    return out


def _check_assessment(where: str, a: object) -> dict[str, Any]:
    if not isinstance(a, dict):
        raise SessionFileError(
            f"{where}: no assessment (a session recorded before ctdrill assessed sessions, or "
            "drill sequences): rehearse it again"
        )
    for name in ASSESSMENT_FIELDS:
        if name not in a:
            raise SessionFileError(
                f"{where}: assessment.{name} is missing; rehearse the session again"
            )
        value = a[name]
        if name in BOOL_FIELDS:
            ok = isinstance(value, bool)
        elif name in INT_FIELDS:
            ok = isinstance(value, int) and not isinstance(value, bool) and value >= 0
        else:
            ok = (value is None and name in NULLABLE_FIELDS) or (
                isinstance(value, int | float)
                and not isinstance(value, bool)
                and math.isfinite(value)
            )
        if not ok:
            raise SessionFileError(f"{where}: assessment.{name} = {value!r} is not a valid value")
    return a


def _trace(where: str, data: bytes) -> dict[str, np.ndarray]:
    """``session.csv`` at :data:`TRACE_RATE_HZ` (float32 arrays)."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SessionFileError(f"{where}: session.csv is not UTF-8 text") from exc
    reader = csv.reader(io.StringIO(text))
    header = next(reader, None)
    want = ["time_s", "master_mm", "drill_mm", "force_cmd_n"]
    if header is None or header[:4] != want:
        raise SessionFileError(f"{where}: session.csv does not start with {','.join(want)}")
    out: list[list[float]] = []
    next_t = -math.inf
    for lineno, row in enumerate(reader, start=2):
        try:
            t = float(row[0])
            if t + 1e-9 < next_t:
                continue
            values = [t, float(row[1]), float(row[2]), float(row[3])]
        except (ValueError, IndexError) as exc:
            raise SessionFileError(
                f"{where}: session.csv line {lineno} is not a number row"
            ) from exc
        if not all(math.isfinite(v) for v in values):
            raise SessionFileError(f"{where}: session.csv line {lineno} holds a non-finite value")
        out.append(values)
        next_t = t + 1.0 / TRACE_RATE_HZ
    arr = np.asarray(out, dtype=np.float32).reshape(-1, 4)
    return {name: arr[:, i].copy() for i, name in enumerate(TRACE_ARRAYS)}


def _no_file(folder: Path, path: Path) -> SessionFileError:
    return SessionFileError(
        f"{folder}: no {path.relative_to(folder)}; give a folder written by ctdrill rehearse "
        "--out (or exported from the window)"
    )


def _read_csv(folder: Path, path: Path) -> bytes:
    if not path.is_file():
        raise _no_file(folder, path)
    return read_bytes_bounded(
        path, what="session log", error=SessionFileError, max_bytes=MAX_SESSION_CSV_BYTES
    )


def _read_files(folder: Path, base: Path, summary_bytes: bytes) -> SessionFiles:
    """A drill's (or a session's) files in ``base``."""
    table = base / TABLE_FILE
    if not table.is_file():
        raise SessionFileError(
            f"{folder}: no {table.relative_to(folder)} (a session recorded before sessions "
            "were assessed from their trace, or not written by ctdrill rehearse): rehearse it "
            "again"
        )
    display = base / DISPLAY_FILE
    return SessionFiles(
        summary_bytes,
        _read_csv(folder, base / "session.csv"),
        read_bytes_bounded(
            table, what="session table", error=SessionFileError, max_bytes=MAX_SUMMARY_BYTES
        ),
        _read_csv(folder, display) if display.is_file() else None,
    )


def read_session(folder: Path) -> SessionEntry:
    """Read a rehearsal's folder (``ctdrill rehearse --out``, or the window's export, whose
    ``session/`` holds it; a drill sequence's folder is one session: module docstring) and
    check its assessment.

    Raises
    ------
    SessionFileError
        No ``summary.json`` or ``session.csv``, unreadable files, no or bad assessment.
    """
    base = folder / "session" if (folder / "session" / "summary.json").is_file() else folder
    summary_path = base / "summary.json"
    if not summary_path.is_file():
        raise _no_file(folder, summary_path)
    summary_bytes = read_bytes_bounded(
        summary_path, what="session summary", error=SessionFileError, max_bytes=MAX_SUMMARY_BYTES
    )
    summary = _summary(folder, summary_bytes)
    if _one_session(summary):
        return session_entry(folder, _read_files(folder, base, summary_bytes))
    drills = []
    for name in _drills(summary):
        sub = base / name / "summary.json"
        if not sub.is_file():
            raise _no_file(folder, sub)
        sub_bytes = read_bytes_bounded(
            sub, what="session summary", error=SessionFileError, max_bytes=MAX_SUMMARY_BYTES
        )
        drills.append((name, _read_files(folder, base / name, sub_bytes)))
    return sequence_entry(folder, summary_bytes, drills)


def _summary(folder: Path, summary_bytes: bytes) -> dict[str, Any]:
    """The checked ``summary.json``: a JSON object with a valid assessment and a plan hash."""
    where = str(folder / "summary.json")
    try:
        text = summary_bytes.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise SessionFileError(f"{where}: not UTF-8 text") from exc
    summary = loads_json(text, where=where, what="session summary", error=SessionFileError)
    if not isinstance(summary, dict):
        raise SessionFileError(f"{where}: not a rehearsal summary (a JSON object)")
    _check_assessment(where, summary.get("assessment"))
    if not isinstance(summary.get("plan_sha256"), str):
        raise SessionFileError(
            f"{where}: plan_sha256 is missing (a session recorded before ctdrill assessed "
            "sessions): rehearse it again"
        )
    return summary


def _one_session(summary: dict[str, Any]) -> bool:
    """One rehearsal's summary (the export's fields and ``rehearsal``; before them, no
    ``format``), not a sequence's listing."""
    from ctdrill.engine.summary import REHEARSAL_FORMAT

    return summary.get("format") is None or summary.get("rehearsal") == REHEARSAL_FORMAT


def _drills(summary: dict[str, Any]) -> list[str]:
    """The drill folders a sequence's listing names, checked (``drill_1``, ``drill_2`` ...)."""
    from ctdrill.app.rehearse_sequence import SEQUENCE_FORMAT  # a sequence only: not at start
    from ctdrill.engine.sequence import drill_folder

    fmt = summary.get("format")
    drills = summary.get("drills")
    if fmt != SEQUENCE_FORMAT or not isinstance(drills, list) or not drills:
        raise SessionFileError(
            f"summary.json: format {fmt!r} is not a rehearsal's ({SEQUENCE_FORMAT!r} with its "
            "drills, or none for one drill); give a folder written by ctdrill rehearse --out"
        )
    names = [d.get("folder") if isinstance(d, dict) else None for d in drills]
    want = [drill_folder(k) for k in range(len(drills))]
    if names != want:
        raise SessionFileError(
            f"summary.json: the sequence's drills name the folders {names}, not {want}; "
            "rehearse it again"
        )
    return want


def _checked(where: Path, summary: dict[str, Any], files: SessionFiles) -> dict[str, Any]:
    """The assessment recomputed from ``files``' trace and table; the summary (its plan
    hash, depths and assessment) must agree with them."""
    table, context, plan = read_table(str(where / TABLE_FILE), files.table)
    csv_text = _text(where / "session.csv", files.csv)
    display = None if files.display is None else _text(where / DISPLAY_FILE, files.display)
    computed = recompute(str(where), csv_text, table, context, display).to_json()
    claims: list[tuple[str, object, object]] = [("plan_sha256", summary.get("plan_sha256"), plan)]
    for key, value in (
        ("planned_depth_mm", context.planned_depth_mm),
        ("max_safe_depth_mm", context.max_safe_depth_mm),
    ):
        claimed = summary.get(key)
        if isinstance(claimed, int | float) and not isinstance(claimed, bool):
            same = math.isclose(float(claimed), value, abs_tol=1e-3) or claimed == value
            claims.append((key, claimed, claimed if same else value))
    for key, claimed, actual in claims:
        if claimed != actual:
            raise SessionFileError(
                f"{where / 'summary.json'}: {key} is {claimed!r} but its {TABLE_FILE} says "
                f"{actual!r}: the summary does not belong to this session; store the folder "
                "ctdrill rehearse wrote, unedited"
            )
    differs = first_disagreement(summary["assessment"], computed)
    if differs is not None:
        name, claimed, actual = differs
        raise SessionFileError(
            f"{where / 'summary.json'}: assessment.{name} is {claimed!r} but the session's "
            f"trace gives {actual!r}: the summary disagrees with session.csv (edited?); store "
            "the folder ctdrill rehearse wrote, unedited"
        )
    return computed


def _text(where: Path, data: bytes) -> str:
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SessionFileError(f"{where}: not UTF-8 text") from exc


def session_entry(folder: Path, files: SessionFiles) -> SessionEntry:
    """A session from its files' bytes (the window stores the session it holds this way, with
    the hash ``ctdrill assess`` gives its exported folder).

    Raises
    ------
    SessionFileError
        Not a rehearsal summary, no table, a bad ``session.csv``, or a summary that disagrees
        with the trace (the first field that differs named).
    """
    summary = _summary(folder, files.summary)
    assessment = _checked(folder, summary, files)
    trace = _trace(str(folder / "session.csv"), files.csv)
    table, context, _ = read_table(str(folder / TABLE_FILE), files.table)
    del table
    safe = context.max_safe_depth_mm
    return SessionEntry(
        folder,
        session_hash(_parts(files)),
        summary,
        trace,
        assessment,
        context.planned_depth_mm,
        safe if math.isfinite(safe) else None,
    )


def sequence_entry(
    folder: Path, summary_bytes: bytes, drills: list[tuple[str, SessionFiles]]
) -> SessionEntry:
    """A drill sequence as one session: its listing ``summary.json`` and each drill's
    ``(folder name, files)`` in drilling order. Each drill's assessment is recomputed from its
    files (its summary must agree), the sequence's combined from them (the listing's must
    agree). The trace is the drills' one after the other (each drill's times after the
    previous one's last, one trace step apart); the hash covers every drill's files.

    Raises
    ------
    SessionFileError
        As :func:`session_entry`, naming the drill.
    """
    summary = _summary(folder, summary_bytes)
    parts: list[dict[str, np.ndarray]] = []
    assessments: list[dict[str, Any]] = []
    hashed: list[tuple[str, bytes]] = []
    offset = 0.0
    planned = math.nan
    for name, files in drills:
        sub = _summary(folder / name, files.summary)
        assessments.append(_checked(folder / name, sub, files))
        part = _trace(str(folder / name / "session.csv"), files.csv)
        part["time_s"] = (part["time_s"].astype(np.float64) + offset).astype(np.float32)
        if part["time_s"].size:
            offset = float(part["time_s"][-1]) + 1.0 / TRACE_RATE_HZ
        parts.append(part)
        hashed += _parts(files, f"{name}/")
        planned = float(sub.get("planned_depth_mm", planned))
    n = summary.get("drills_planned")
    n = n if isinstance(n, int) and not isinstance(n, bool) and n >= len(drills) else len(drills)
    whole = summary.get("planned_depth_mm")
    if isinstance(whole, int | float) and not isinstance(whole, bool):
        planned = float(whole)
    combined = combine_assessments(assessments, drills_planned=n, planned_depth_mm=planned)
    differs = first_disagreement(summary["assessment"], combined.to_json())
    if differs is not None:
        name, claimed, actual = differs
        raise SessionFileError(
            f"{folder / 'summary.json'}: assessment.{name} is {claimed!r} but the drills' "
            f"traces give {actual!r}: the summary disagrees with the sessions; store the folder "
            "ctdrill rehearse wrote, unedited"
        )
    trace = {a: np.concatenate([p[a] for p in parts]) for a in TRACE_ARRAYS}
    return SessionEntry(
        folder,
        session_hash(hashed),
        summary,
        trace,
        combined.to_json(),
        planned,
        None,
    )
