"""``ctdrill inspect PATH`` (or ``--ct PATH``): load a CT (a DICOM series, or a NIfTI, NRRD or
MetaImage file) and describe its geometry, HU and warnings."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from ctdrill.app.commands.options import CT_HELP, OneCt, add_series_option
from ctdrill.app.errors import AppInputError


def register(subparsers: Any) -> None:
    """Add the ``inspect`` subcommand."""
    p = subparsers.add_parser(
        "inspect",
        help="describe a CT: DICOM series, NIfTI, NRRD, MetaImage (geometry, HU range, warnings)",
        description="Load a CT and print its geometry, HU range and load warnings.",
    )
    p.add_argument("dicom", type=Path, nargs="?", metavar="PATH", help=CT_HELP)
    p.add_argument(
        "--ct", type=Path, default=None, action=OneCt, metavar="PATH", help="the same as PATH"
    )
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
    from ctdrill.imaging import load_ct
    from ctdrill.imaging.dicom.report import format_report, volume_report
    from ctdrill.imaging.volumes.load import listed_series

    if (args.dicom is None) == (args.ct is None):
        raise AppInputError("inspect: name the CT once, as PATH or as --ct PATH")
    path = args.dicom if args.ct is None else args.ct
    volume = load_ct(path, series_uid=args.series)
    series = listed_series(path, volume)
    report = volume_report(volume, series=series, include_phi=args.include_phi)
    if args.json:
        sys.stdout.write(json.dumps(report, indent=1) + "\n")
    else:
        sys.stdout.write(format_report(report) + "\n")
    return 0
