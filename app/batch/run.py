"""Run a manifest: resume, the runners, the status table and the cohort's table.

Output folder ``DIR``:

- ``rows/<id>/``: each row's export (as ``ctdrill export`` writes it) plus its marker
  (:data:`ctdrill.app.batch.task.ROW_MARKER`), swapped in whole;
- ``status.csv``: one line per manifest row, ``row, id, dicom, plan, status, folder, seconds,
  resumed``; ``status`` is ``ok`` or the ``error:`` line;
- ``trajectories.csv``: every trajectory of every row that is ok, the columns of
  :mod:`ctdrill.app.export_table` after ``row, id, dicom, plan`` (``folder`` relative to
  ``DIR``);
- ``batch.json``: the manifest's name and hash, the options, the counts.

No absolute path reaches these three files: a row's paths are shown relative to the manifest,
or hashed when outside its folder (:func:`ctdrill.app.batch.manifest.display_path`), and so
are the paths error lines name; text cells that a spreadsheet would run are neutralised
(:mod:`ctdrill.app.csv_cells`). The tables are written (atomically) when the batch ends,
also after Ctrl-C, with what is true then: a row whose output is complete is ``ok``.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
from collections.abc import Callable, Iterable, Sequence
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

from ctdrill.app.batch.inputs import forget_digests
from ctdrill.app.batch.manifest import (
    BatchInputError,
    ManifestRow,
    display_path,
    redact_paths,
)
from ctdrill.app.batch.task import (
    REMOVED_TAG,
    ROW_MARKER,
    ExportSettings,
    RowOutcome,
    RowTask,
    fingerprint,
    is_complete,
    is_unsealed,
    one_line,
    remove_row_output,
)
from ctdrill.app.batch.workers import NOT_RUN, Interrupt, run_processes, run_serial
from ctdrill.app.export_table import TABLE_COLUMNS, TABLE_NAME, TEXT_COLUMNS, table_csv, table_row
from ctdrill.app.records import atomic_write_text, clean_leftovers
from ctdrill.engine.summary import TrajectorySummary, read_summary
from ctdrill.safeio import load_json

__all__ = ["BatchInputError", "BatchReport", "run_batch"]

STATUS_NAME = "status.csv"
BATCH_NAME = "batch.json"
ROWS_DIR = "rows"
STATUS_COLUMNS = ("row", "id", "dicom", "plan", "status", "folder", "seconds", "resumed")
STATUS_TEXT = frozenset({"id", "dicom", "plan", "status", "folder", "resumed"})
COHORT_COLUMNS = ("row", "id", "dicom", "plan", *TABLE_COLUMNS)
COHORT_TEXT = frozenset({"id", "dicom", "plan"}) | TEXT_COLUMNS
#: Exit code of a batch that ran with some rows failed (0: all ok; 2: bad input; 1: a bug).
EXIT_ROWS_FAILED = 4
#: Exit code of a batch stopped by Ctrl-C (its tables written).
EXIT_INTERRUPTED = 130
#: Largest summary read back from a row folder.
MAX_SUMMARY_BYTES = 64 * 1024 * 1024

Progress = Callable[[int, int, RowOutcome], None]


@dataclass(frozen=True)
class BatchReport:
    """What a batch did: one outcome per manifest row, in manifest order."""

    outcomes: tuple[RowOutcome, ...]
    out_dir: Path
    interrupted: bool = False
    #: The exit code after an interrupt: ``128 + signal`` (130 Ctrl-C, 143 SIGTERM, 129 SIGHUP).
    interrupt_exit: int = EXIT_INTERRUPTED

    @property
    def failed(self) -> tuple[RowOutcome, ...]:
        """The rows that failed (or were not run)."""
        return tuple(o for o in self.outcomes if not o.ok)

    @property
    def not_run(self) -> tuple[RowOutcome, ...]:
        """The rows Ctrl-C kept from running."""
        return tuple(o for o in self.outcomes if o.status == NOT_RUN)

    def summary_line(self) -> str:
        """``batch: N rows: K ok (R resumed), F failed; status in DIR/status.csv``."""
        n_ok = sum(o.ok for o in self.outcomes)
        resumed = sum(o.resumed for o in self.outcomes)
        failed = len(self.failed) - len(self.not_run)
        extra = f", {len(self.not_run)} not run (interrupted)" if self.not_run else ""
        return (
            f"batch: {len(self.outcomes)} rows: {n_ok} ok ({resumed} resumed), "
            f"{failed} failed{extra}; status in {self.out_dir / STATUS_NAME}"
        )


def _check_out_dir(out: Path) -> None:
    """``DIR`` is new, empty, or a batch's folder; anything else is refused (nothing of the
    user's is overwritten)."""
    if not out.exists():
        return
    if not out.is_dir():
        raise BatchInputError(f"--out {out}: exists and is not a folder; choose another --out")
    ours = {ROWS_DIR, STATUS_NAME, TABLE_NAME, BATCH_NAME}
    leftover = re.compile(r"^\..*\.ctdrill-(tmp|new|old)-")
    foreign = [p.name for p in out.iterdir() if p.name not in ours and not leftover.match(p.name)]
    if foreign:
        names = ", ".join(sorted(foreign)[:3]) + (", ..." if len(foreign) > 3 else "")
        raise BatchInputError(
            f"--out {out}: holds files ctdrill batch did not write ({names}); "
            "choose a new or empty folder"
        )


def _complete(r: ManifestRow, out: Path, fp: str | None, base: Path) -> bool:
    """The row's folder is complete for ``fp`` and its tables can be read."""
    if not is_complete(out / ROWS_DIR / r.row_id, fp, base):
        return False
    try:
        _row_trajectories(r, out)
    except (OSError, ValueError, KeyError, TypeError):
        return False
    return True


def plan_tasks(
    rows: Sequence[ManifestRow], out: Path, options: ExportSettings, base: Path
) -> tuple[list[RowTask], list[RowOutcome]]:
    """Split the rows into tasks to run and outcomes of rows already complete (resume)."""
    tasks: list[RowTask] = []
    done: list[RowOutcome] = []
    for r in rows:
        fp = fingerprint(r.dicom_path, r.plan_path, options)
        if _complete(r, out, fp, base):
            done.append(RowOutcome(row=r.row, status="ok", seconds=0.0, resumed=True))
            continue
        tasks.append(
            RowTask(
                row=r.row,
                row_id=r.row_id,
                dicom=r.dicom,
                plan=r.plan,
                dicom_path=str(r.dicom_path),
                plan_path=str(r.plan_path),
                out_dir=str(out / ROWS_DIR / r.row_id),
                options=options,
                fingerprint=fp,
                base=str(base),
            )
        )
    return tasks, done


def _clean_leftovers(rows: Sequence[ManifestRow], rows_dir: Path) -> None:
    """Remove what killed runs left in ``rows/``: staging folders of a row's swap and a
    marker's temporary file (those of a live process stay:
    :func:`ctdrill.app.records.clean_leftovers`) and failed rows' old folders being removed.
    Row ids never start with ``.``, so no row folder is taken for one of these."""
    for r in rows:
        clean_leftovers(rows_dir / r.row_id)
        if (rows_dir / r.row_id).is_dir():
            clean_leftovers(rows_dir / r.row_id / ROW_MARKER)
    for p in rows_dir.iterdir():
        if p.name.startswith(".") and REMOVED_TAG in p.name:
            shutil.rmtree(p, ignore_errors=True)


def run_batch(
    manifest: Path,
    rows: Sequence[ManifestRow],
    out: Path,
    options: ExportSettings,
    *,
    workers: int,
    scheduler: str | None = None,
    progress: Progress | None = None,
    stop: Interrupt | None = None,
) -> BatchReport:
    """Export every row not already complete, then write the three tables.

    ``workers`` 1 runs in this process; more use a process pool; ``scheduler`` a Dask
    cluster (``workers`` is then the cluster's business). Ctrl-C (SIGTERM, SIGHUP) stops the
    batch (``stop``, the caller's :class:`ctdrill.app.batch.workers.Interrupt` when it
    installed one before reading the manifest, else this call's): the report says
    ``interrupted`` and the tables record which rows are complete, whenever it came.
    """
    if stop is None:
        with Interrupt() as own:
            return run_batch(
                manifest,
                rows,
                out,
                options,
                workers=workers,
                scheduler=scheduler,
                progress=progress,
                stop=own,
            )
    if workers < 1:
        raise BatchInputError(f"--workers must be 1 or more, got {workers}")
    forget_digests()  # every input hashed afresh: a file replaced since is seen
    _check_out_dir(out)
    client = None
    if scheduler is not None:
        from ctdrill.app.batch.cluster import connect

        client = connect(scheduler)
    base = Path(os.path.abspath(manifest)).parent
    rows_dir = out / ROWS_DIR
    rows_dir.mkdir(parents=True, exist_ok=True)
    _clean_leftovers(rows, rows_dir)
    outcomes: dict[int, RowOutcome] = {}

    def on_done(o: RowOutcome) -> None:
        outcomes[o.row] = o
        if progress is not None:
            progress(len(outcomes), len(rows), o)

    try:
        tasks, done = plan_tasks(rows, out, options, base)
        for o in done:
            on_done(o)
        if stop.stopping:
            tasks = []
        if client is not None:
            from ctdrill.app.batch.cluster import run_dask

            run_dask(tasks, client, on_done, stop)
        elif workers == 1 or len(tasks) <= 1:
            run_serial(tasks, on_done, stop)
        else:
            run_processes(tasks, min(workers, len(tasks)), on_done, stop)
    except KeyboardInterrupt:  # a second Ctrl-C outside a row
        stop.count = max(stop.count, 2)
    report = _finish(manifest, rows, out, options, outcomes, base)
    return replace(report, interrupted=stop.stopping, interrupt_exit=stop.exit_code)


def _finish(
    manifest: Path,
    rows: Sequence[ManifestRow],
    out: Path,
    options: ExportSettings,
    outcomes: dict[int, RowOutcome],
    base: Path,
) -> BatchReport:
    """Write ``status.csv``, ``trajectories.csv`` and ``batch.json``.

    A row without an outcome (Ctrl-C) whose folder is complete for its inputs is ``ok``; the
    others are ``error: not run (the batch was interrupted)``.
    """
    final: list[RowOutcome] = []
    status_rows: list[dict[str, str]] = []
    cohort: list[dict[str, str]] = []
    for r in rows:
        o = outcomes.get(r.row)
        if o is None:
            fp = fingerprint(r.dicom_path, r.plan_path, options)
            ok = _complete(r, out, fp, base)
            o = RowOutcome(row=r.row, status="ok" if ok else NOT_RUN, seconds=0.0)
            folder = out / ROWS_DIR / r.row_id
            if not ok and is_unsealed(folder):  # a worker cancelled between its swap and
                remove_row_output(folder)  # its seal: no row folder is half a result
        if o.ok:
            try:
                cohort += _row_trajectories(r, out)
            except (OSError, ValueError, KeyError, TypeError) as exc:
                o = replace(o, status=one_line(f"error: its output cannot be read: {exc}"))
        o = replace(o, status=_shown(o.status, r, base))
        final.append(o)
        status_rows.append(
            {
                "row": str(r.row),
                "id": r.row_id,
                "dicom": r.dicom,
                "plan": r.plan,
                "status": o.status,
                "folder": f"{ROWS_DIR}/{r.row_id}" if o.ok else "",
                "seconds": f"{o.seconds:.3f}",
                "resumed": "true" if o.resumed else "false",
            }
        )
    atomic_write_text(out / STATUS_NAME, table_csv(status_rows, STATUS_COLUMNS, STATUS_TEXT))
    atomic_write_text(out / TABLE_NAME, table_csv(cohort, COHORT_COLUMNS, COHORT_TEXT))
    doc = {
        "format": "ctdrill-batch/1",
        "manifest": manifest.name,
        "manifest_sha256": _file_sha256(manifest),
        "options": _shown_options(options, base),
        "rows": len(rows),
        "ok": sum(o.ok for o in final),
        "resumed": sum(o.resumed for o in final),
        "failed": sum(not o.ok and o.status != NOT_RUN for o in final),
        "not_run": sum(o.status == NOT_RUN for o in final),
    }
    atomic_write_text(out / BATCH_NAME, json.dumps(doc, indent=2) + "\n")
    return BatchReport(outcomes=tuple(final), out_dir=out)


def _shown(status: str, r: ManifestRow, base: Path) -> str:
    """A status line naming the row's files as the tables show them (no absolute path)."""
    return redact_paths(status, [(r.dicom_path, r.dicom), (r.plan_path, r.plan)], base)


def _shown_options(options: ExportSettings, base: Path) -> dict[str, Any]:
    doc = asdict(options)
    cal = options.calibration
    if cal is not None and (os.sep in cal or cal.lower().endswith(".json")):
        doc["calibration"] = display_path(Path(cal), base)
    return doc


def _file_sha256(path: Path) -> str | None:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        return None


def _summary(path: Path) -> dict[str, Any]:
    doc = load_json(path, what="row summary", error=ValueError, max_bytes=MAX_SUMMARY_BYTES)
    if not isinstance(doc, dict):
        raise ValueError(f"{path}: not a summary document")
    return doc


def _row_trajectories(r: ManifestRow, out: Path) -> list[dict[str, str]]:
    """The cohort table's rows of one complete row folder."""
    import csv

    folder = out / ROWS_DIR / r.row_id
    rel = f"{ROWS_DIR}/{r.row_id}"
    head = {"row": str(r.row), "id": r.row_id, "dicom": r.dicom, "plan": r.plan}
    summary = folder / "summary.json"
    if summary.is_file():
        read = read_summary(_summary(summary))
        if isinstance(read, TrajectorySummary):
            return [{**head, **table_row(read, rel)}]
        rows = []  # a drill sequence: one row per drill, from the drill's own summary
        for drill in read.drills:
            one = TrajectorySummary.from_json(_summary(folder / drill.folder / "summary.json"))
            rows.append({**head, **table_row(one, f"{rel}/{drill.folder}")})
        return rows
    with (folder / TABLE_NAME).open(newline="", encoding="utf-8") as fh:
        got = list(csv.DictReader(fh))
    # projected on today's columns: a row written by another version of the table reads too
    return [
        {
            **head,
            **{k: t.get(k) or "" for k in TABLE_COLUMNS},
            "folder": f"{rel}/{t['folder']}" if t.get("folder") else "",
        }
        for t in got
    ]


def default_workers() -> int:
    """One worker per core this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def outcome_lines(report: BatchReport, rows: Iterable[ManifestRow]) -> list[str]:
    """One terminal line per failed row: ``row N (id): error: ...`` (not the rows Ctrl-C kept
    from running: the summary counts them)."""
    ids = {r.row: r.row_id for r in rows}
    return [f"row {o.row} ({ids[o.row]}): {o.status}" for o in report.failed if o.status != NOT_RUN]
