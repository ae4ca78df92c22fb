"""Calibration recordings on disk: the manifest and the slave robot's force recordings.

Manifest CSV, header ``file, hu, feed_mm_s`` (paths relative to the manifest). Recording CSV,
header ``time_s, position_mm, force_n`` (extra columns are ignored). Every problem raises a
:class:`RecordingError` naming the file, the row or column, and what to do.
"""

from __future__ import annotations

import csv
import io
import math
import os
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ctdrill.model.errors import ModelInputError
from ctdrill.safeio import read_bytes_bounded

MANIFEST_COLUMNS: tuple[str, ...] = ("file", "hu", "feed_mm_s")
RECORDING_COLUMNS: tuple[str, ...] = ("time_s", "position_mm", "force_n")
#: Largest manifest or recording read, bytes (a 10 kHz recording of 10 minutes is ~180 MB).
MAX_CSV_BYTES = 256 * 1024 * 1024


class RecordingError(ModelInputError):
    """A manifest or a recording is missing, malformed, or unusable for calibration."""


@dataclass(frozen=True)
class ManifestEntry:
    """One manifest row: a recording at a known CT number and feed."""

    path: Path
    hu: float
    feed_mm_s: float


@dataclass(frozen=True, eq=False)
class Recording:
    """A force recording, shape (N,) each, time strictly increasing."""

    path: Path
    time_s: np.ndarray
    position_mm: np.ndarray
    force_n: np.ndarray


def _read_text(path: Path, what: str) -> str:
    """The UTF-8 text of a manifest or recording: a regular file of bounded size.

    A FIFO would block ``open`` forever and ``/dev/zero`` would read until memory runs out:
    both are refused by name, before anything is read.
    """
    try:
        exists = os.path.lexists(path)
    except ValueError:  # a NUL byte in the name
        exists = True
    if not exists:
        raise RecordingError(f"{what} {path}: not found; check the path")
    try:
        data = read_bytes_bounded(path, what=what, error=RecordingError, max_bytes=MAX_CSV_BYTES)
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise RecordingError(
            f"{what} {path}: cannot read it (not UTF-8 text: {exc.reason} at byte {exc.start})"
        ) from exc


def _read_header(path: Path, what: str) -> tuple[list[str], list[list[str]]]:
    text = _read_text(path, what)
    try:
        rows = [
            row
            for row in csv.reader(io.StringIO(text, newline=""))
            if row and any(c.strip() for c in row)
        ]
    except (csv.Error, ValueError) as exc:  # a NUL inside the text
        raise RecordingError(f"{what} {path}: cannot read it ({exc})") from exc
    if not rows:
        raise RecordingError(f"{what} {path}: empty; it needs a header line and data rows")
    return [c.strip() for c in rows[0]], rows[1:]


def _clip(text: str, limit: int = 80) -> str:
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _column_index(header: list[str], names: tuple[str, ...], path: Path, what: str) -> list[int]:
    missing = [n for n in names if n not in header]
    if missing and len(header) == 1 and any(sep in header[0] for sep in ";\t"):
        raise RecordingError(
            f"{what} {path}: columns must be separated by commas, not semicolons or tabs "
            f"(header {_clip(header[0])!r})"
        )
    if missing:
        raise RecordingError(
            f"{what} {path}: missing column {', '.join(missing)}; the header must name "
            f"{', '.join(names)} (found {_clip(', '.join(header)) or 'nothing'})"
        )
    return [header.index(n) for n in names]


def read_manifest(path: str | Path) -> list[ManifestEntry]:
    """Read a calibration manifest; recording paths are resolved relative to it."""
    mpath = Path(path)
    header, rows = _read_header(mpath, "manifest")
    i_file, i_hu, i_feed = _column_index(header, MANIFEST_COLUMNS, mpath, "manifest")
    if not rows:
        raise RecordingError(f"manifest {mpath}: no recordings listed; add rows under the header")
    entries: list[ManifestEntry] = []
    for line, row in enumerate(rows, start=2):
        if len(row) < len(header):
            raise RecordingError(
                f"manifest {mpath}, line {line}: {len(row)} fields, expected {len(header)}"
            )
        values: dict[str, float] = {}
        for name, idx in (("hu", i_hu), ("feed_mm_s", i_feed)):
            try:
                values[name] = float(row[idx])
            except ValueError:
                values[name] = math.nan
            if not math.isfinite(values[name]):
                raise RecordingError(
                    f"manifest {mpath}, line {line}, column {name}: {row[idx].strip()!r} "
                    "is not a finite number"
                )
        if values["feed_mm_s"] <= 0.0:
            raise RecordingError(
                f"manifest {mpath}, line {line}, column feed_mm_s: must be > 0 mm/s "
                "(a cutting feed)"
            )
        rel = row[i_file].strip()
        if not rel:
            raise RecordingError(f"manifest {mpath}, line {line}, column file: empty")
        entries.append(
            ManifestEntry(path=(mpath.parent / rel), hu=values["hu"], feed_mm_s=values["feed_mm_s"])
        )
    return entries


def _parse_rows(rows: list[list[str]], idx: list[int], rpath: Path) -> np.ndarray:
    """Slow path that names the first bad field (line, column)."""
    data = np.empty((len(rows), len(idx)))
    for r, row in enumerate(rows):
        for c, i in enumerate(idx):
            text = row[i].strip() if i < len(row) else ""
            try:
                data[r, c] = float(text)
            except ValueError:
                raise RecordingError(
                    f"recording {rpath}, line {r + 2}, column {RECORDING_COLUMNS[c]}: "
                    f"{text!r} is not a number"
                ) from None
    return data


def read_recording(path: str | Path) -> Recording:
    """Read one recording CSV (``time_s, position_mm, force_n``; extra columns ignored)."""
    rpath = Path(path)
    text = _read_text(rpath, "recording")
    try:
        first = next(csv.reader([text.partition("\n")[0]]), [])
    except (csv.Error, ValueError) as exc:  # a NUL in the header
        raise RecordingError(f"recording {rpath}: cannot read it ({exc})") from exc
    header = [c.strip() for c in first]
    idx = _column_index(header, RECORDING_COLUMNS, rpath, "recording")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # "input contained no data"
            data = np.loadtxt(io.StringIO(text), delimiter=",", skiprows=1, usecols=idx, ndmin=2)
    except ValueError:
        _, rows = _read_header(rpath, "recording")
        data = _parse_rows(rows, idx, rpath)
    if data.shape[0] < 16:
        raise RecordingError(
            f"recording {rpath}: only {data.shape[0]} samples; record at least a few seconds"
        )
    bad = ~np.isfinite(data)
    if bad.any():
        r, c = np.argwhere(bad)[0]
        raise RecordingError(
            f"recording {rpath}, line {r + 2}, column {RECORDING_COLUMNS[c]}: not finite"
        )
    time_s = data[:, 0]
    if np.any(np.diff(time_s) <= 0.0):
        r = int(np.argmax(np.diff(time_s) <= 0.0)) + 3
        raise RecordingError(
            f"recording {rpath}, line {r}, column time_s: time must strictly increase"
        )
    return Recording(path=rpath, time_s=time_s, position_mm=data[:, 1], force_n=data[:, 2])
