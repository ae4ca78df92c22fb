"""A rehearsal's folder as the trainee record reads it: ``summary.json`` (its assessment) and
``session.csv`` (the replay trace), and the session's content hash.

A drill sequence's folder (``ctdrill rehearse`` of a plan with ``drills``: ``drill_k/`` per
drill and a listing ``summary.json``) is one session: the listing's ``assessment`` (the
sequence's, combined from its drills'), and as its trace the drills' ``session.csv`` one after
the other; its hash covers the listing and every drill's log. A drill's own folder is that
drill alone.
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

from ctdrill.app.errors import AppInputError
from ctdrill.haptics.assessment import (
    ASSESSMENT_FIELDS,
    BOOL_FIELDS,
    INT_FIELDS,
    NULLABLE_FIELDS,
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


class SessionFileError(AppInputError):
    """A session folder that cannot be recorded (the message names the file and why)."""


@dataclass(frozen=True, eq=False)
class SessionEntry:
    """One session folder, read and checked, ready to store."""

    folder: Path
    session_hash: str
    summary: dict[str, Any]
    trace: dict[str, np.ndarray]

    @property
    def assessment(self) -> dict[str, Any]:
        """The summary's ``assessment``."""
        out: dict[str, Any] = self.summary["assessment"]
        return out


def session_hash(summary_bytes: bytes, csv_bytes: bytes) -> str:
    """The session's content hash: SHA-256 of its ``summary.json`` and ``session.csv``."""
    h = hashlib.sha256(b"ctdrill-session/1\0")
    h.update(len(summary_bytes).to_bytes(8, "little") + summary_bytes)
    h.update(csv_bytes)
    return h.hexdigest()


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
        return session_entry(folder, summary_bytes, _read_csv(folder, base / "session.csv"))
    logs = [(name, _read_csv(folder, base / name / "session.csv")) for name in _drills(summary)]
    return sequence_entry(folder, summary_bytes, logs)


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


def session_entry(folder: Path, summary_bytes: bytes, csv_bytes: bytes) -> SessionEntry:
    """A session from its ``summary.json`` and ``session.csv`` bytes (the window stores the
    session it holds this way, with the hash ``ctdrill assess`` gives its exported folder).

    Raises
    ------
    SessionFileError
        Not a rehearsal summary, no or bad assessment, no plan hash, a bad ``session.csv``.
    """
    summary = _summary(folder, summary_bytes)
    trace = _trace(str(folder / "session.csv"), csv_bytes)
    return SessionEntry(folder, session_hash(summary_bytes, csv_bytes), summary, trace)


def sequence_entry(
    folder: Path, summary_bytes: bytes, logs: list[tuple[str, bytes]]
) -> SessionEntry:
    """A drill sequence as one session: its listing ``summary.json`` (the sequence's
    assessment) and each drill's ``(folder name, session.csv bytes)`` in drilling order. The
    trace is the drills' one after the other (each drill's times after the previous one's
    last, one trace step apart); the hash covers the listing and every log, each named and
    sized.

    Raises
    ------
    SessionFileError
        As :func:`session_entry`, naming the drill's log.
    """
    summary = _summary(folder, summary_bytes)
    parts: list[dict[str, np.ndarray]] = []
    offset = 0.0
    for name, data in logs:
        part = _trace(str(folder / name / "session.csv"), data)
        part["time_s"] = (part["time_s"].astype(np.float64) + offset).astype(np.float32)
        if part["time_s"].size:
            offset = float(part["time_s"][-1]) + 1.0 / TRACE_RATE_HZ
        parts.append(part)
    trace = {a: np.concatenate([p[a] for p in parts]) for a in TRACE_ARRAYS}
    joined = b"".join(f"{name}\0{len(data)}\0".encode() + data for name, data in logs)
    return SessionEntry(folder, session_hash(summary_bytes, joined), summary, trace)
