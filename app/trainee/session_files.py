"""A rehearsal's folder as the trainee record reads it: ``summary.json`` (its assessment) and
``session.csv`` (the replay trace), and the session's content hash."""

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
            f"{where}: no assessment (a drill sequence, or a session recorded before ctdrill "
            "assessed sessions): rehearse it again"
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


def read_session(folder: Path) -> SessionEntry:
    """Read a rehearsal's folder (``ctdrill rehearse --out``, or the window's export, whose
    ``session/`` holds it) and check its assessment.

    Raises
    ------
    SessionFileError
        No ``summary.json`` or ``session.csv``, unreadable files, no or bad assessment.
    """
    base = folder / "session" if (folder / "session" / "summary.json").is_file() else folder
    summary_path, csv_path = base / "summary.json", base / "session.csv"
    for path in (summary_path, csv_path):
        if not path.is_file():
            raise SessionFileError(
                f"{folder}: no {path.name}; give a folder written by ctdrill rehearse --out "
                "(or exported from the window)"
            )
    summary_bytes = read_bytes_bounded(
        summary_path, what="session summary", error=SessionFileError, max_bytes=MAX_SUMMARY_BYTES
    )
    csv_bytes = read_bytes_bounded(
        csv_path, what="session log", error=SessionFileError, max_bytes=MAX_SESSION_CSV_BYTES
    )
    return session_entry(folder, summary_bytes, csv_bytes)


def session_entry(folder: Path, summary_bytes: bytes, csv_bytes: bytes) -> SessionEntry:
    """A session from its ``summary.json`` and ``session.csv`` bytes (the window stores the
    session it holds this way, with the hash ``ctdrill assess`` gives its exported folder).

    Raises
    ------
    SessionFileError
        Not a rehearsal summary, no or bad assessment, no plan hash, a bad ``session.csv``.
    """
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
    trace = _trace(str(folder / "session.csv"), csv_bytes)
    return SessionEntry(folder, session_hash(summary_bytes, csv_bytes), summary, trace)
