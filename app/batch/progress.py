"""The batch's progress on stdout (stderr is kept for ``error:`` lines): a ``rich`` progress
bar on a terminal (rows done, elapsed and remaining time), one plain line per finished row
otherwise (logs, CI, pipes)."""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator, Mapping
from typing import TextIO

from ctdrill.app.batch.task import RowOutcome

ProgressFn = Callable[[int, int, RowOutcome], None]


@contextlib.contextmanager
def make_progress(stream: TextIO, ids: Mapping[int, str]) -> Iterator[ProgressFn]:
    """Yield the callback :func:`ctdrill.app.batch.run.run_batch` calls per finished row."""
    total = len(ids)

    def label(o: RowOutcome) -> str:
        what = "ok (complete, skipped)" if o.resumed else o.status
        return f"row {o.row} ({ids.get(o.row, '?')}): {what}"

    if not stream.isatty():

        def plain(done: int, n: int, o: RowOutcome) -> None:
            stream.write(f"batch [{done}/{n}] {label(o)}\n")
            stream.flush()

        yield plain
        return

    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    console = Console(file=stream)
    bar = Progress(
        TextColumn("batch"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        TextColumn("{task.description}"),
        console=console,
    )
    with bar:
        task = bar.add_task("", total=total)

        def fancy(done: int, n: int, o: RowOutcome) -> None:
            if not o.ok:
                bar.console.print(label(o), markup=False, highlight=False)
            bar.update(task, completed=done, description=label(o)[:60])

        yield fancy
