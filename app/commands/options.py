"""Options several commands share, defined once (standard library only: ``--help`` stays light)."""

from __future__ import annotations

import argparse
from pathlib import Path


def add_plan_option(parser: argparse.ArgumentParser, *, required: bool) -> None:
    """``--plan PLAN...``: repeatable; files and folders merge into one plan."""
    parser.add_argument(
        "--plan",
        type=Path,
        required=required,
        nargs="+",
        action="extend",
        metavar="PLAN",
        help="ctdrill-plan/1 JSON, 3D Slicer .mrk.json or segmentation (.seg.nrrd, .nrrd, "
        ".nii.gz, DICOM SEG); repeatable, or a folder: all merge into one plan",
    )


def add_interpolate_gaps_option(parser: argparse.ArgumentParser) -> None:
    """``--interpolate-gaps``: interpolate across gaps the drill crosses, stated in the output."""
    parser.add_argument(
        "--interpolate-gaps",
        action="store_true",
        help="interpolate HU across slice gaps (steps over 1.5 x the nominal slice step) the "
        "drill crosses, instead of refusing; summary.json then states them (interpolated_gaps) "
        "with warning gap_interpolated",
    )
