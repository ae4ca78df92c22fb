"""``ctdrill batch``: export every row of a manifest (a cohort), with resume and a status table."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from ctdrill.app.commands.options import (
    add_grey_map_options,
    add_hu_sigma_option,
    add_interpolate_gaps_option,
    add_override_options,
    add_placement_option,
)
from ctdrill.engine.settings import DEFAULT_RATE_HZ


def register(subparsers: Any) -> None:
    """Add the ``batch`` subcommand."""
    p = subparsers.add_parser(
        "batch",
        help="export every case of a manifest (dicom, plan per row) with resume",
        description=(
            "Export every row of MANIFEST.csv (columns dicom, plan, optionally id; paths "
            "relative to the manifest) into DIR/rows/<id>/, one worker process per core, "
            "then write DIR/status.csv (ok or the error line per row), DIR/trajectories.csv "
            "(every trajectory of every case) and DIR/batch.json. Rows whose output is "
            "complete and whose inputs are unchanged are skipped (resume). One bad case "
            "never stops the batch. Exit code 0 when every row is ok, 4 when some failed, "
            "2 for a bad manifest or options. See docs/batch.md."
        ),
    )
    p.add_argument("manifest", type=Path, metavar="MANIFEST.csv", help="the manifest")
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="output folder")
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help="worker processes (default: one per core; 1 runs in this process)",
    )
    p.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="run on a dask.distributed cluster (tcp://HOST:8786; needs ctdrill[cluster] and "
        "a file system the workers share at the same paths)",
    )
    add_override_options(p)
    p.add_argument(
        "--rate-hz",
        type=float,
        default=DEFAULT_RATE_HZ,
        help=f"force.csv sample rate (default {DEFAULT_RATE_HZ:g})",
    )
    p.add_argument("--no-plot", action="store_true", help="no force.png (screening)")
    p.add_argument(
        "--per-trajectory",
        action="store_true",
        help="rows with several trajectories: also each one's files",
    )
    add_interpolate_gaps_option(p)
    add_placement_option(p)
    add_hu_sigma_option(p)
    add_grey_map_options(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the batch; print the summary line and each failed row. Ctrl-C (SIGTERM, SIGHUP)
    from here on still writes ``status.csv`` (every row not run) and exits ``128 + signal``."""
    from ctdrill.app.batch.workers import Interrupt

    with Interrupt() as stop:
        return _run(args, stop)


def _run(args: argparse.Namespace, stop: Any) -> int:
    from ctdrill.app.batch.manifest import read_manifest
    from ctdrill.app.batch.progress import make_progress
    from ctdrill.app.batch.run import (
        EXIT_ROWS_FAILED,
        BatchInputError,
        default_workers,
        outcome_lines,
        run_batch,
    )
    from ctdrill.app.commands.options import export_settings
    from ctdrill.engine.grey import hu_sigma_uncertainty

    for name, value in (("--feed-mm-s", args.feed_mm_s), ("--rate-hz", args.rate_hz)):
        if value is not None and not value > 0.0:
            raise BatchInputError(f"{name} must be a positive number, got {value!r}")
    hu_sigma_uncertainty(args.hu_sigma)  # a bad --hu-sigma is one error line, not N rows
    rows = read_manifest(args.manifest)
    options = export_settings(args)
    workers = default_workers() if args.workers is None else args.workers
    with make_progress(sys.stdout, {r.row: r.row_id for r in rows}) as progress:
        report = run_batch(
            args.manifest,
            rows,
            args.out,
            options,
            workers=workers,
            scheduler=args.scheduler,
            progress=progress,
            stop=stop,
        )
    sys.stdout.write(report.summary_line() + "\n")
    for line in outcome_lines(report, rows):
        sys.stderr.write(line + "\n")
    if report.interrupted:
        sys.stderr.write(
            f"error: interrupted: {len(report.not_run)} rows not run, the others recorded in "
            f"{report.out_dir / 'status.csv'}; run the same command again to resume\n"
        )
        return report.interrupt_exit
    return EXIT_ROWS_FAILED if report.failed else 0
