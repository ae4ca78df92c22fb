"""``ctdrill inspect DIR``: load a DICOM CT series and describe its geometry, HU and warnings."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from ctdrill.app.commands.options import add_series_option


def register(subparsers: Any) -> None:
    """Add the ``inspect`` subcommand."""
    p = subparsers.add_parser(
        "inspect",
        help="describe a DICOM CT series (geometry, HU range, warnings)",
        description="Load a DICOM CT series and print its geometry, HU range and load warnings.",
    )
    p.add_argument("dicom", type=Path, metavar="DIR", help="DICOM folder (or one file)")
    p.add_argument("--json", action="store_true", help="print JSON instead of text")
    add_series_option(p)
    p.add_argument(
        "--include-phi",
        action="store_true",
        help="print the raw SeriesInstanceUIDs and the study/series descriptions (free text "
        "that often holds a name); by default series are named by the SHA-256 of their UID",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Load, describe, print."""
    from ctdrill.imaging import list_series, load_series
    from ctdrill.imaging.dicom.report import format_report, volume_report

    volume = load_series(args.dicom, series_uid=args.series)
    report = volume_report(volume, series=list_series(args.dicom), include_phi=args.include_phi)
    if args.json:
        sys.stdout.write(json.dumps(report, indent=1) + "\n")
    else:
        sys.stdout.write(format_report(report) + "\n")
    return 0
