"""One manifest row as a task: what a worker runs, what it returns, and when a row is complete.

A row's output folder ``DIR/rows/<id>/`` is written by :func:`ctdrill.app.export_run.export_case`
in one atomic swap, together with ``batch-row.json`` (:data:`ROW_MARKER`), which records the
row's input fingerprint and the identities of the other files it read; once the swap is done
the worker seals the marker with the size and SHA-256 of every file the row wrote (an atomic
rewrite). A row is *complete* when that folder exists and its sealed marker agrees with the
inputs now and with the files there (:mod:`ctdrill.app.batch.inputs`): a changed input (the
series, the plan, a mask or calibration the plan names, the options, the ctdrill version)
or a damaged output (a truncated ``summary.json``) makes the row run again. A kill between
the swap and the seal leaves an unsealed marker: the row is redone.
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
from ctdrill.app.batch.inputs import (
    add_tree,
    input_records,
    inputs_unchanged,
    output_digests,
    outputs_intact,
    row_inputs,
    volume_files,
)
from ctdrill.app.errors import AppInputError
from ctdrill.engine.settings import ExportSettings
from ctdrill.safeio import load_json

#: The marker written last (in the same swap) into a row's output folder.
ROW_MARKER = "batch-row.json"
ROW_FORMAT = "ctdrill-batch-row/2"
#: Tag of a failed row's earlier folder while it is removed (a leftover after a kill is
#: removed by the next batch).
REMOVED_TAG = "ctdrill-batch-removed"
#: Largest row marker read back (a marker lists a row's files: a few kB).
MAX_MARKER_BYTES = 16 * 1024 * 1024


@dataclass(frozen=True)
class RowTask:
    """Everything a worker needs for one row (plain data: it crosses process boundaries).

    ``dicom`` and ``plan`` are the cells as shown in the outputs (relative to the manifest
    or hashed: :func:`ctdrill.app.batch.manifest.display_path`); ``base`` is the manifest's
    folder, against which the marker records the other inputs.
    """

    row: int
    row_id: str
    dicom: str
    plan: str
    dicom_path: str
    plan_path: str
    out_dir: str
    options: ExportSettings
    fingerprint: str | None
    base: str = "."


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


def fingerprint(dicom: Path, plan: Path, options: ExportSettings) -> str | None:
    """The row's input fingerprint (:mod:`ctdrill.app.batch.inputs`, 1): the options, the
    ctdrill version, the series (each file by relative path and content) and the plan path
    by content; None when an input cannot be read or the series path is not a
    series folder (the row then runs and reports why)."""
    from ctdrill.imaging.dicom.discovery import check_series_folder
    from ctdrill.imaging.errors import ImagingInputError

    h = hashlib.sha256()
    head = {"format": ROW_FORMAT, "ctdrill": ctdrill.__version__, "options": asdict(options)}
    h.update(json.dumps(head, sort_keys=True).encode())
    try:
        if not dicom.exists() or not plan.exists():
            return None
        check_series_folder(dicom)  # "/" is refused before it is walked
        for f in volume_files(dicom):  # a folder, or a volume file and its data file
            add_tree(h, "dicom", f)
        add_tree(h, "plan", plan)
    except (OSError, ImagingInputError):
        return None
    return h.hexdigest()


def marker_doc(task: RowTask, inputs: list[list[str]] | None) -> dict[str, Any]:
    """The row marker before the seal (no ``outputs``: an unsealed row is not complete)."""
    return {
        "format": ROW_FORMAT,
        "row": task.row,
        "id": task.row_id,
        "dicom": task.dicom,
        "plan": task.plan,
        "fingerprint": task.fingerprint,
        "inputs": inputs,
    }


def _read_marker(out_dir: Path) -> dict[str, Any] | None:
    try:
        doc = load_json(
            out_dir / ROW_MARKER, what="row marker", error=AppInputError, max_bytes=MAX_MARKER_BYTES
        )
    except AppInputError:
        return None
    return doc if isinstance(doc, dict) else None


def is_complete(out_dir: Path, fp: str | None, base: Path) -> bool:
    """The row's folder holds a whole, sealed output made from inputs with fingerprint ``fp``
    whose other inputs (recorded against ``base``, the manifest's folder) are unchanged."""
    if fp is None:
        return False
    doc = _read_marker(out_dir)
    return (
        doc is not None
        and doc.get("format") == ROW_FORMAT
        and doc.get("fingerprint") == fp
        and inputs_unchanged(doc.get("inputs"), base)
        and outputs_intact(doc.get("outputs"), out_dir)
    )


def seal_row(out_dir: Path, doc: dict[str, Any]) -> None:
    """Rewrite the row's marker (atomically) with the size and SHA-256 of every file the row
    wrote."""
    from ctdrill.app.records import atomic_write_text

    sealed = {**doc, "outputs": output_digests(out_dir, skip=ROW_MARKER)}
    atomic_write_text(out_dir / ROW_MARKER, json.dumps(sealed, indent=2) + "\n")


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
    from ctdrill.app.errors import INPUT_ERRORS
    from ctdrill.app.export_run import export_case

    t0 = time.perf_counter()
    opts = task.options
    base = Path(task.base)
    try:
        inputs: list[list[str]] | None = input_records(
            row_inputs(Path(task.plan_path), opts.calibration), base
        )
    except Exception:  # the export below reports why; an unsealed row is never complete
        inputs = None
    doc = marker_doc(task, inputs)
    try:
        from ctdrill.app.exercise.blind import blind_guard

        blind_guard("batch", plans=[Path(task.plan_path)], ct=Path(task.dicom_path), keyed=False)
        export_case(
            Path(task.dicom_path),
            [Path(task.plan_path)],
            Path(task.out_dir),
            opts,
            extra_files={ROW_MARKER: json.dumps(doc, indent=2) + "\n"},
        )
        if inputs is not None:
            seal_row(Path(task.out_dir), doc)
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


def is_unsealed(out_dir: Path) -> bool:
    """``out_dir`` holds a row marker that was never sealed (a worker killed between the
    row's swap and its seal): half a row's result, not an earlier output."""
    if not (out_dir / ROW_MARKER).is_file():
        return False
    doc = _read_marker(out_dir)
    return doc is None or "outputs" not in doc


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
