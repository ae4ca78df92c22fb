"""The batch manifest: a CSV file with columns ``ct`` (or ``dicom``), ``plan`` (and an optional
``id``).

Paths are relative to the manifest's folder (absolute paths are kept). Each data row is one
case: a CT (a DICOM series folder or file, a NIfTI, NRRD or MetaImage file) and a plan (a
file or a folder of plans, as ``--plan`` takes). ``id`` names the row's output folder
(default: the row number); ids are kept to letters, digits, ``._-``, at most
:data:`MAX_ID_CHARS` characters, must not start with ``.`` (the batch's own staging and
removal names do) and must be unique ignoring case (two folders on a case-insensitive file
system). A manifest that cannot be read as such is bad input (one ``error:`` line, exit 2); a
row whose files are missing or bad is a failed row, reported in the status table while the
others run.

Outputs name a row's files by :func:`display_path`: relative to the manifest's folder, or,
for a path outside it, by a hash (no user's or patient's folder name in ``status.csv``,
``trajectories.csv``, ``batch.json``).
"""

from __future__ import annotations

import csv
import hashlib
import io
import os
import re
from dataclasses import dataclass
from pathlib import Path

from ctdrill.app.errors import AppInputError
from ctdrill.safeio import read_bytes_bounded

REQUIRED_COLUMNS = ("dicom", "plan")
OPTIONAL_COLUMNS = ("id",)
#: The CT column may be named ``ct`` (a DICOM folder or a NIfTI, NRRD or MetaImage file, as
#: ``--ct`` takes); it is read as ``dicom``.
CT_COLUMN = "ct"
#: A manifest is a small text file; a larger one is refused before it is read.
MAX_MANIFEST_BYTES = 64 * 1024 * 1024
#: An id: letters, digits, ``._-``, not starting with ``.`` (hidden names are the runner's).
_ID = re.compile(r"^[A-Za-z0-9_-][A-Za-z0-9._-]*$")
#: Longest id (a folder name, with room for the staging names built from it).
MAX_ID_CHARS = 100


class ManifestError(AppInputError):
    """The manifest cannot be read (exit 2)."""


class BatchInputError(AppInputError):
    """Bad batch options, scheduler or output folder (exit 2)."""


@dataclass(frozen=True)
class ManifestRow:
    """One case of the manifest.

    Attributes
    ----------
    row : 1-based number of the data row (the header is row 0).
    dicom, plan : the cells as outputs show them (:func:`display_path`).
    dicom_path, plan_path : resolved against the manifest's folder (absolute).
    row_id : the output folder's name (``id`` or the zero-padded row number).
    """

    row: int
    dicom: str
    plan: str
    dicom_path: Path
    plan_path: Path
    row_id: str


def read_manifest(path: Path) -> list[ManifestRow]:
    """Read and check the manifest ``path``; raise :class:`ManifestError` naming what is wrong."""
    raw = read_bytes_bounded(
        path, what="manifest", error=ManifestError, max_bytes=MAX_MANIFEST_BYTES
    )
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ManifestError(
            f"{path}: not UTF-8 text (byte {exc.start}); save the manifest as UTF-8 CSV"
        ) from None
    reader = csv.reader(io.StringIO(text, newline=""))
    try:
        rows = [r for r in reader]
    except csv.Error as exc:
        raise ManifestError(f"{path}: not a CSV file ({exc}); columns dicom, plan") from None
    if not rows:
        raise ManifestError(f"{path}: empty; it needs a header line 'dicom,plan' and rows")
    header = [h.strip() for h in rows[0]]
    if CT_COLUMN in header:
        if "dicom" in header:
            raise ManifestError(f"{path}: columns ct and dicom both name the CT; keep one")
        header[header.index(CT_COLUMN)] = "dicom"
    missing = [c for c in REQUIRED_COLUMNS if c not in header]
    unknown = [c for c in header if c not in REQUIRED_COLUMNS + OPTIONAL_COLUMNS]
    if missing or unknown:
        what = f"missing column(s) {', '.join(missing)}" if missing else ""
        if unknown:
            what += ("; " if what else "") + f"unknown column(s) {', '.join(map(repr, unknown))}"
        raise ManifestError(
            f"{path}: {what}; the header must name ct (or dicom), plan (and optionally id)"
        )
    if len(set(header)) != len(header):
        raise ManifestError(f"{path}: a column is named twice in the header {header}")
    col = {name: header.index(name) for name in header}
    base = path.parent
    data = [(n, r) for n, r in enumerate(rows[1:], start=1) if any(c.strip() for c in r)]
    if not data:
        raise ManifestError(f"{path}: no rows below the header; add one row per case")
    width = max(4, len(str(data[-1][0])))
    out: list[ManifestRow] = []
    seen: dict[str, int] = {}
    for n, r in data:
        if len(r) != len(header):
            raise ManifestError(
                f"{path}: row {n} has {len(r)} cells, the header {len(header)}; "
                "quote cells that hold commas"
            )
        cells = {name: r[i].strip() for name, i in col.items()}
        for name in REQUIRED_COLUMNS:
            if not cells[name]:
                raise ManifestError(f"{path}: row {n}: column {name} is empty")
        row_id = cells.get("id") or f"{n:0{width}d}"
        if not _ID.match(row_id) or len(row_id) > MAX_ID_CHARS:
            raise ManifestError(
                f"{path}: row {n}: id {row_id!r} must be letters, digits, '.', '_' or '-', "
                f"not start with '.', at most {MAX_ID_CHARS} characters"
            )
        key = row_id.casefold()
        if key in seen:
            raise ManifestError(
                f"{path}: rows {seen[key]} and {n} have the same id {row_id!r} (ignoring "
                "case); ids name the output folders and must be unique"
            )
        seen[key] = n
        dicom_path = Path(os.path.abspath(base / cells["dicom"]))
        plan_path = Path(os.path.abspath(base / cells["plan"]))
        out.append(
            ManifestRow(
                row=n,
                dicom=display_path(dicom_path, base),
                plan=display_path(plan_path, base),
                dicom_path=dicom_path,
                plan_path=plan_path,
                row_id=row_id,
            )
        )
    return out


#: How a path outside the manifest's folder is shown: this prefix and 16 hex digits of the
#: SHA-256 of its absolute path (the same path, the same name; no folder names).
HASHED_PATH_PREFIX = "sha256:"


def hashed_path(path: Path) -> str:
    """``path`` as records name it without any folder name: :data:`HASHED_PATH_PREFIX` and
    16 hex digits of the SHA-256 of its absolute path (the same path, the same name)."""
    digest = hashlib.sha256(os.fsencode(os.path.abspath(path))).hexdigest()[:16]
    return f"{HASHED_PATH_PREFIX}{digest}"


def display_path(path: Path, base: Path) -> str:
    """``path`` as outputs show it: relative to ``base`` (the manifest's folder, POSIX
    separators) when inside it, else :data:`HASHED_PATH_PREFIX` and a hash."""
    absolute = os.path.abspath(path)
    rel = os.path.relpath(absolute, os.path.abspath(base))
    if rel != os.pardir and not rel.startswith(os.pardir + os.sep) and not os.path.isabs(rel):
        return Path(rel).as_posix()
    return hashed_path(Path(absolute))


def redact_paths(text: str, rows: list[tuple[Path, str]], base: Path) -> str:
    """``text`` with the absolute paths it names shown as :func:`display_path` shows them.

    ``rows``: (absolute path, its display) of the row's series and plan, longest first
    replaced, so a file inside either is named through it; then the manifest's folder
    becomes relative, and any other absolute path left is hashed whole.
    """
    known = sorted(rows, key=lambda r: len(str(r[0])), reverse=True)
    for path, shown in known:
        text = text.replace(str(path), shown)
    prefix = os.path.abspath(base) + os.sep
    text = text.replace(prefix, "")
    return _ABSOLUTE.sub(lambda m: display_path(Path(m.group(0)), base), text)


#: An absolute POSIX path in a message: a ``/`` that starts a word, up to a space, a quote,
#: a colon, a comma or a semicolon.
_ABSOLUTE = re.compile(r"(?<![\w.~/])/[^\s:,;'\"()]+")
