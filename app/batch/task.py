"""One manifest row as a task: what a worker runs, what it returns, and when a row is complete.

A row's output folder ``DIR/rows/<id>/`` is written by :func:`ctdrill.app.export_run.export_case`
in one atomic swap, together with ``batch-row.json`` (:data:`ROW_MARKER`), which records the
row's **input fingerprint**. A row is *complete* when that folder exists and its marker holds
the fingerprint of the row's inputs now: the folder cannot exist half-written (the swap), and
a changed input (another series, an edited plan, other export options, another ctdrill
version) changes the fingerprint, so the row is redone.

The fingerprint (SHA-256) covers: the options that shape the files, the ctdrill version, and
every file under the row's DICOM folder and plan path (a file or a folder) by relative path,
size and modification time (nanoseconds), plus the content of the plan files of up to
:data:`HASHED_PLAN_BYTES` each (plans are small; an edit that keeps the size and the
timestamp is still seen). A calibration given as a file (``--calibration PATH``) counts the
same way. Files a plan names outside its own folder (a mask landmark's ``path``) are not
fingerprinted: touch the plan when such a file changes.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import ctdrill
from ctdrill.app.grey_option import GreyMapSpec

#: The marker written last (in the same swap) into a row's output folder.
ROW_MARKER = "batch-row.json"
ROW_FORMAT = "ctdrill-batch-row/1"
#: Tag of a failed row's earlier folder while it is removed (a leftover after a kill is
#: removed by the next batch).
REMOVED_TAG = "ctdrill-batch-removed"
#: Plan files up to this size are hashed by content as well.
HASHED_PLAN_BYTES = 4 * 1024 * 1024


@dataclass(frozen=True)
class ExportOptions:
    """The export options every row shares (``ctdrill batch`` flags)."""

    calibration: str | None = None
    feed_mm_s: float | None = None
    rate_hz: float = 1000.0
    plot: bool = True
    per_trajectory: bool = False
    interpolate_gaps: bool = False
    hu_sigma: float | None = None
    grey: GreyMapSpec | None = None


@dataclass(frozen=True)
class RowTask:
    """Everything a worker needs for one row (plain data: it crosses process boundaries)."""

    row: int
    row_id: str
    dicom: str
    plan: str
    dicom_path: str
    plan_path: str
    out_dir: str
    options: ExportOptions
    fingerprint: str | None


@dataclass(frozen=True)
class RowOutcome:
    """A row's result: ``status`` is ``ok`` or the ``error:`` line the export would print."""

    row: int
    status: str
    seconds: float
    resumed: bool = False

    @property
    def ok(self) -> bool:
        """The row's output is complete."""
        return self.status == "ok"


def _walk(root: Path) -> list[Path]:
    if root.is_file():
        return [root]
    out: list[Path] = []
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames.sort()
        out += [Path(dirpath) / f for f in sorted(filenames)]
    return out


def _add_tree(h: Any, kind: str, root: Path, *, hash_content: bool) -> None:
    for path in _walk(root):
        st = path.stat()
        rel = path.relative_to(root).as_posix() if path != root else path.name
        h.update(f"{kind}\0{rel}\0{st.st_size}\0{st.st_mtime_ns}\n".encode())
        if hash_content and st.st_size <= HASHED_PLAN_BYTES:
            h.update(hashlib.sha256(path.read_bytes()).digest())


def fingerprint(dicom: Path, plan: Path, options: ExportOptions) -> str | None:
    """The row's input fingerprint (see the module docstring); None when an input cannot be
    read (the row then runs and reports why)."""
    h = hashlib.sha256()
    head = {"format": ROW_FORMAT, "ctdrill": ctdrill.__version__, "options": asdict(options)}
    h.update(json.dumps(head, sort_keys=True).encode())
    try:
        if not dicom.exists() or not plan.exists():
            return None
        _add_tree(h, "dicom", dicom, hash_content=False)
        _add_tree(h, "plan", plan, hash_content=True)
        if options.calibration is not None and Path(options.calibration).is_file():
            _add_tree(h, "calibration", Path(options.calibration), hash_content=True)
    except OSError:
        return None
    return h.hexdigest()


def marker_json(task: RowTask) -> str:
    """The row marker's text."""
    doc = {
        "format": ROW_FORMAT,
        "row": task.row,
        "id": task.row_id,
        "dicom": task.dicom,
        "plan": task.plan,
        "fingerprint": task.fingerprint,
    }
    return json.dumps(doc, indent=2) + "\n"


def is_complete(out_dir: Path, fp: str | None) -> bool:
    """The row's folder holds a whole output made from inputs with fingerprint ``fp``."""
    if fp is None:
        return False
    try:
        doc = json.loads((out_dir / ROW_MARKER).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return isinstance(doc, dict) and doc.get("fingerprint") == fp


def one_line(text: str) -> str:
    """A message on one line (a status cell, a terminal line)."""
    return " ".join(str(text).split())


def run_row(task: RowTask) -> RowOutcome:
    """Export one row into ``task.out_dir`` (the function every worker runs).

    Never raises for a bad case: bad input becomes the ``error:`` line ``ctdrill export``
    would print, anything else (a bug) ``error: internal error ...`` with its type, so one
    bad case never stops the batch. A failed row leaves no output folder (an earlier one,
    made from other inputs, is removed: it would not be this row's result).
    """
    from ctdrill.app.cli import INPUT_ERRORS
    from ctdrill.app.export_run import export_case

    t0 = time.perf_counter()
    opts = task.options
    try:
        export_case(
            Path(task.dicom_path),
            [Path(task.plan_path)],
            Path(task.out_dir),
            calibration=opts.calibration,
            feed_mm_s=opts.feed_mm_s,
            rate_hz=opts.rate_hz,
            interpolate_gaps=opts.interpolate_gaps,
            plot=opts.plot,
            per_trajectory=opts.per_trajectory,
            hu_sigma=opts.hu_sigma,
            grey=opts.grey,
            extra_files={ROW_MARKER: marker_json(task)},
        )
        status = "ok"
    except INPUT_ERRORS as exc:
        status = one_line(f"error: {exc}")
    except OSError as exc:
        where = f"{exc.filename}: " if exc.filename else ""
        status = one_line(f"error: {where}{exc.strerror or exc}; check the path")
    except Exception as exc:  # a bug: reported on the row, the batch goes on
        status = one_line(
            f"error: internal error (a bug, please report it): {type(exc).__name__}: {exc}"
        )
    if status != "ok":
        remove_row_output(Path(task.out_dir))
    return RowOutcome(row=task.row, status=status, seconds=time.perf_counter() - t0)


def remove_row_output(out_dir: Path) -> None:
    """Remove a row folder a batch wrote earlier (it holds the row marker); else leave it."""
    if not (out_dir / ROW_MARKER).is_file():
        return
    aside = out_dir.with_name(f".{out_dir.name}.{REMOVED_TAG}-{os.getpid()}")
    try:
        out_dir.rename(aside)
    except OSError:
        return
    shutil.rmtree(aside, ignore_errors=True)
