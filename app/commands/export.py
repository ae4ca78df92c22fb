"""``ctdrill export``: force/HU/clearance tables, summary and plot for planned trajectories."""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path
from typing import Any

from ctdrill.app.commands.options import (
    add_ct_option,
    add_grey_map_options,
    add_hu_sigma_option,
    add_interpolate_gaps_option,
    add_override_options,
    add_placement_option,
    add_plan_option,
    add_series_option,
)
from ctdrill.engine.settings import DEFAULT_RATE_HZ


def register(subparsers: Any) -> None:
    """Add the ``export`` subcommand."""
    p = subparsers.add_parser(
        "export",
        help="export force, HU and clearance along planned trajectories (headless)",
        description=(
            "Load a DICOM CT series once, sample it along each planned drill trajectory and "
            "write force.csv, profile.csv, summary.json and force.png. Several trajectories "
            "(plans, or a folder of plans) write one table, OUT/trajectories.csv, one row per "
            "trajectory, and with --per-trajectory also OUT/<plan name>/ with each one's "
            "files. A plan with a drill sequence (drills) writes OUT/drill_1/, OUT/drill_2/ "
            "... and a summary.json listing them. No patient identifiers are written unless "
            "--include-phi."
        ),
    )
    add_ct_option(p, required=True)
    add_plan_option(p, required=True)
    p.add_argument("--out", type=Path, required=True, metavar="OUT", help="output folder")
    add_override_options(p)
    p.add_argument(
        "--rate-hz",
        type=float,
        default=DEFAULT_RATE_HZ,
        help=f"force.csv sample rate (default {DEFAULT_RATE_HZ:g})",
    )
    p.add_argument(
        "--include-phi",
        action="store_true",
        help="write the patient's name, ID, birth date and institution, and the raw "
        "SeriesInstanceUID, into summary.json (by default the UID's SHA-256 only)",
    )
    add_series_option(p)
    add_interpolate_gaps_option(p)
    add_placement_option(p)
    p.add_argument(
        "--no-plot",
        action="store_true",
        help='do not draw force.png (screening; each summary.json says "plot": false)',
    )
    p.add_argument(
        "--per-trajectory",
        action="store_true",
        help="with several trajectories, also write each one's files into OUT/<plan name>/ "
        "(by default only OUT/trajectories.csv)",
    )
    add_hu_sigma_option(p)
    add_grey_map_options(p)
    p.set_defaults(func=run)


def _warn(code: str, message: str) -> None:
    """Show a warning the user must see before the run (``no_landmarks``)."""
    sys.stderr.write(f"warning: {message}\n")


def _in_sequence(path: Path, written: list[Path]) -> bool:
    """A drill's summary inside a sequence folder (its sequence's summary prints its lines)."""
    return path.parent.name.startswith("drill_") and path.parent.parent / "summary.json" in written


def run(args: argparse.Namespace) -> int:
    """Export and list what was written."""
    from ctdrill.app.commands.options import export_settings
    from ctdrill.app.export_run import export_case
    from ctdrill.app.export_table import TABLE_NAME, table_lines
    from ctdrill.app.summary_lines import summary_lines
    from ctdrill.app.text_progress import TextProgress
    from ctdrill.engine.summary import read_summary

    settings = export_settings(args)
    progress = TextProgress(sys.stdout)
    try:
        written = export_case(
            args.dicom, args.plan, args.out, settings, progress=progress, warn=_warn
        )
    finally:
        progress.close()
    for path in written:
        sys.stdout.write(f"wrote {path}\n")
    summaries = [p for p in written if p.name == "summary.json" and not _in_sequence(p, written)]
    for path in summaries:
        summary = read_summary(json.loads(path.read_text(encoding="utf-8")))
        sys.stdout.write("".join(line + "\n" for line in summary_lines(summary)))
    if not summaries:
        for path in written:
            if path.name == TABLE_NAME:
                with path.open(newline="", encoding="utf-8") as fh:
                    lines = table_lines(csv.DictReader(fh))
                sys.stdout.write("".join(line + "\n" for line in lines))
    return 0
