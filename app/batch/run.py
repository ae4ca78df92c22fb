"""Run a manifest: resume, the runners, the status table and the cohort's table.

Output folder ``DIR``:

- ``rows/<id>/``: each row's export (as ``ctdrill export`` writes it) plus its marker
  (:data:`ctdrill.app.batch.task.ROW_MARKER`), swapped in whole;
- ``status.csv``: one line per manifest row, ``row, id, dicom, plan, status, folder, seconds,
  resumed``; ``status`` is ``ok`` or the ``error:`` line;
- ``trajectories.csv``: every trajectory of every row that is ok, the columns of
  :mod:`ctdrill.app.export_table` after ``row, id, dicom, plan`` (``folder`` relative to
  ``DIR``);
- ``batch.json``: the manifest, the options, the counts.

The three tables are written (atomically) when the batch ends, also after Ctrl-C.
"""

from __future__ import annotations

import csv
import json
import os
import re
import shutil
from collections.abc import Callable, Iterable, Sequence
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ctdrill.app.batch.manifest import ManifestRow
from ctdrill.app.batch.task import (
    REMOVED_TAG,
    ExportOptions,
    RowOutcome,
    RowTask,
    fingerprint,
    is_complete,
    one_line,
    run_row,
)
from ctdrill.app.errors import AppInputError
from ctdrill.app.export_table import TABLE_COLUMNS, TABLE_NAME, table_csv, table_row
from ctdrill.app.records import atomic_write_text, clean_leftovers
from ctdrill.app.sequence_export import SEQUENCE_FORMAT

STATUS_NAME = "status.csv"
BATCH_NAME = "batch.json"
ROWS_DIR = "rows"
STATUS_COLUMNS = ("row", "id", "dicom", "plan", "status", "folder", "seconds", "resumed")
COHORT_COLUMNS = ("row", "id", "dicom", "plan", *TABLE_COLUMNS)
#: Exit code of a batch that ran with some rows failed (0: all ok; 2: bad input; 1: a bug).
EXIT_ROWS_FAILED = 4

if TYPE_CHECKING:
    from multiprocessing.context import BaseContext

Progress = Callable[[int, int, RowOutcome], None]
#: Modules the forkserver imports once for every worker it forks.
PRELOAD = (
    "ctdrill.app.batch.task",
    "ctdrill.app.export_run",
    "ctdrill.app.export_plot",
    "matplotlib.figure",
    "matplotlib.backends.backend_agg",
)


class BatchInputError(AppInputError):
    """Bad batch options or output folder (exit 2)."""


@dataclass(frozen=True)
class BatchReport:
    """What a batch did: one outcome per manifest row, in manifest order."""

    outcomes: tuple[RowOutcome, ...]
    out_dir: Path

    @property
    def failed(self) -> tuple[RowOutcome, ...]:
        """The rows that failed."""
        return tuple(o for o in self.outcomes if not o.ok)

    def summary_line(self) -> str:
        """``batch: N rows: K ok (R resumed), F failed; status in DIR/status.csv``."""
        n_ok = sum(o.ok for o in self.outcomes)
        resumed = sum(o.resumed for o in self.outcomes)
        return (
            f"batch: {len(self.outcomes)} rows: {n_ok} ok ({resumed} resumed), "
            f"{len(self.failed)} failed; status in {self.out_dir / STATUS_NAME}"
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


def plan_tasks(
    rows: Sequence[ManifestRow], out: Path, options: ExportOptions
) -> tuple[list[RowTask], list[RowOutcome]]:
    """Split the rows into tasks to run and outcomes of rows already complete (resume)."""
    tasks: list[RowTask] = []
    done: list[RowOutcome] = []
    for r in rows:
        folder = out / ROWS_DIR / r.row_id
        fp = fingerprint(r.dicom_path, r.plan_path, options)
        if is_complete(folder, fp):
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
                out_dir=str(folder),
                options=options,
                fingerprint=fp,
            )
        )
    return tasks, done


def run_serial(tasks: Sequence[RowTask], on_done: Callable[[RowOutcome], None]) -> None:
    """Run the tasks one after another in this process."""
    for task in tasks:
        on_done(run_row(task))


def run_processes(
    tasks: Sequence[RowTask], workers: int, on_done: Callable[[RowOutcome], None]
) -> None:
    """Run the tasks on a pool of ``workers`` processes.

    Workers are forked from a ``forkserver`` (a fresh interpreter that has imported the
    export once, :data:`PRELOAD`), so no state or thread of this process is copied into them
    and each starts without importing NumPy, SciPy and matplotlib again (a 4-case batch on
    2 workers took 6 s instead of 11 s with ``spawn`` here); ``spawn`` where there is no
    forkserver.

    A worker process that dies (killed, out of memory, a crash in a library) breaks the
    pool: the rows it held are run again each in a pool of its own, and a row that kills
    that one too is reported failed; the batch goes on.
    """
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    ctx: BaseContext
    if "forkserver" in multiprocessing.get_all_start_methods():
        server = multiprocessing.get_context("forkserver")
        server.set_forkserver_preload(list(PRELOAD))
        ctx = server
    else:
        ctx = multiprocessing.get_context("spawn")
    broken: list[RowTask] = []
    with ProcessPoolExecutor(max_workers=workers, mp_context=ctx) as pool:
        pending = {pool.submit(run_row, t): t for t in tasks}
        while pending:
            finished, _ = wait(pending, return_when=FIRST_COMPLETED)
            for fut in finished:
                task = pending.pop(fut)
                try:
                    on_done(fut.result())
                except BrokenProcessPool:
                    broken.append(task)
    for task in broken:
        with ProcessPoolExecutor(max_workers=1, mp_context=ctx) as alone:
            try:
                outcome = alone.submit(run_row, task).result()
            except BrokenProcessPool:
                outcome = RowOutcome(
                    row=task.row,
                    status="error: the worker process running this row died (killed, out of "
                    "memory or crashed); run the row alone with ctdrill export to see why",
                    seconds=0.0,
                )
        on_done(outcome)


def connect(address: str) -> Any:
    """A dask.distributed ``Client`` of the scheduler at ``address``; bad input when
    dask.distributed is missing or the scheduler cannot be reached (10 s)."""
    try:
        from distributed import Client
    except ImportError:
        raise BatchInputError(
            "--scheduler needs dask.distributed, which is not installed: "
            "pip install 'ctdrill[cluster]'"
        ) from None
    try:
        return Client(address, timeout="10s")
    except (OSError, TimeoutError, ValueError) as exc:
        raise BatchInputError(
            f"--scheduler {address}: cannot connect ({one_line(str(exc))}); start one with "
            "'dask scheduler' and give its address (tcp://HOST:8786)"
        ) from None


def run_dask(tasks: Sequence[RowTask], client: Any, on_done: Callable[[RowOutcome], None]) -> None:
    """Run the tasks on the dask.distributed cluster of ``client`` (closed at the end).

    Workers write the rows' folders themselves: every path must mean the same on them as
    here (a shared file system mounted at the same place; ``docs/batch.md``).
    """
    from distributed import as_completed

    with client:
        futures = client.map(run_row, list(tasks), pure=False)
        row_of = {f.key: t for f, t in zip(futures, tasks, strict=True)}
        for fut in as_completed(futures):
            task = row_of[fut.key]
            try:
                outcome = fut.result()
            except Exception as exc:  # KilledWorker, a lost connection: the row failed
                outcome = RowOutcome(
                    row=task.row,
                    status=one_line(
                        f"error: the cluster could not run this row: {type(exc).__name__}: {exc}"
                    ),
                    seconds=0.0,
                )
            on_done(outcome)


def _clean_leftovers(rows: Sequence[ManifestRow], rows_dir: Path) -> None:
    """Remove what killed runs left in ``rows/``: staging folders of a row's swap (those of a
    live process stay: :func:`ctdrill.app.records.clean_leftovers`) and failed rows' old
    folders being removed."""
    for r in rows:
        clean_leftovers(rows_dir / r.row_id)
    for p in rows_dir.iterdir():
        if REMOVED_TAG in p.name and p.name.startswith("."):
            shutil.rmtree(p, ignore_errors=True)


def run_batch(
    manifest: Path,
    rows: Sequence[ManifestRow],
    out: Path,
    options: ExportOptions,
    *,
    workers: int,
    scheduler: str | None = None,
    progress: Progress | None = None,
) -> BatchReport:
    """Export every row not already complete, then write the three tables.

    ``workers`` 1 runs in this process; more use a process pool; ``scheduler`` a Dask
    cluster (``workers`` is then the cluster's business).
    """
    if workers < 1:
        raise BatchInputError(f"--workers must be 1 or more, got {workers}")
    _check_out_dir(out)
    client = connect(scheduler) if scheduler is not None else None
    rows_dir = out / ROWS_DIR
    rows_dir.mkdir(parents=True, exist_ok=True)
    _clean_leftovers(rows, rows_dir)
    tasks, done = plan_tasks(rows, out, options)
    outcomes: dict[int, RowOutcome] = {}

    def on_done(o: RowOutcome) -> None:
        outcomes[o.row] = o
        if progress is not None:
            progress(len(outcomes), len(rows), o)

    for o in done:
        on_done(o)
    try:
        if client is not None:
            run_dask(tasks, client, on_done)
        elif workers == 1 or len(tasks) <= 1:
            run_serial(tasks, on_done)
        else:
            run_processes(tasks, min(workers, len(tasks)), on_done)
    finally:
        report = _finish(manifest, rows, out, options, outcomes)
    return report


def _finish(
    manifest: Path,
    rows: Sequence[ManifestRow],
    out: Path,
    options: ExportOptions,
    outcomes: dict[int, RowOutcome],
) -> BatchReport:
    """Write ``status.csv``, ``trajectories.csv`` and ``batch.json`` (rows not run: ``error:
    not run (the batch was interrupted)``)."""
    final: list[RowOutcome] = []
    status_rows: list[dict[str, str]] = []
    cohort: list[dict[str, str]] = []
    for r in rows:
        o = outcomes.get(r.row) or RowOutcome(
            row=r.row, status="error: not run (the batch was interrupted)", seconds=0.0
        )
        if o.ok:
            try:
                cohort += _row_trajectories(r, out)
            except (OSError, ValueError, KeyError) as exc:
                o = replace(o, status=one_line(f"error: its output cannot be read: {exc}"))
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
    atomic_write_text(out / STATUS_NAME, table_csv(status_rows, STATUS_COLUMNS))
    atomic_write_text(out / TABLE_NAME, table_csv(cohort, COHORT_COLUMNS))
    doc = {
        "format": "ctdrill-batch/1",
        "manifest": str(manifest),
        "options": asdict(options),
        "rows": len(rows),
        "ok": sum(o.ok for o in final),
        "resumed": sum(o.resumed for o in final),
        "failed": sum(not o.ok for o in final),
    }
    atomic_write_text(out / BATCH_NAME, json.dumps(doc, indent=2) + "\n")
    return BatchReport(outcomes=tuple(final), out_dir=out)


def _row_trajectories(r: ManifestRow, out: Path) -> list[dict[str, str]]:
    """The cohort table's rows of one complete row folder."""
    folder = out / ROWS_DIR / r.row_id
    rel = f"{ROWS_DIR}/{r.row_id}"
    head = {"row": str(r.row), "id": r.row_id, "dicom": r.dicom, "plan": r.plan}
    summary = folder / "summary.json"
    if summary.is_file():
        doc = json.loads(summary.read_text(encoding="utf-8"))
        if doc.get("format") != SEQUENCE_FORMAT:
            return [{**head, **table_row(doc, rel)}]
        rows = []  # a drill sequence: one row per drill, from the drill's own summary
        for drill in doc["drills"]:
            sub = folder / drill["folder"] / "summary.json"
            one = json.loads(sub.read_text(encoding="utf-8"))
            rows.append({**head, **table_row(one, f"{rel}/{drill['folder']}")})
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
    """One terminal line per failed row: ``row N (id): error: ...``."""
    ids = {r.row: r.row_id for r in rows}
    return [f"row {o.row} ({ids[o.row]}): {o.status}" for o in report.failed]
