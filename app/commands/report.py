"""``ctdrill report``: one PDF of the planned case (summary, panoramic, cross-sections, 3D,
curves), drawn off screen with the export's numbers."""

from __future__ import annotations

import argparse
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


def register(subparsers: Any) -> None:
    """Add the ``report`` subcommand."""
    p = subparsers.add_parser(
        "report",
        help="write a PDF report of the planned case (off screen)",
        description=(
            "Load a DICOM CT series and the plan(s), compute every trajectory as ctdrill "
            "export does, and write one PDF: the summary table (stop depth and reason, max "
            "safe depth, clearances and the binding landmark, drills, implants, calibration "
            "and whether it is illustrative, every warning), the panoramic reformat with the "
            "implants (the plan needs a dental arch, arch_mm), a cross-section per "
            "trajectory, a 3D view, and per trajectory the force, HU and clearance against "
            "depth. No display is needed. No patient identifiers are written unless "
            "--include-phi. See docs/report.md."
        ),
    )
    add_ct_option(p, required=True)
    add_plan_option(p, required=True)
    p.add_argument("--out", type=Path, required=True, metavar="PDF", help="the report to write")
    add_override_options(p)
    p.add_argument(
        "--include-phi",
        action="store_true",
        help="write the patient's name, ID, birth date and institution, and the raw "
        "SeriesInstanceUID, into the report (by default the UID's SHA-256 only)",
    )
    add_series_option(p)
    add_interpolate_gaps_option(p)
    add_placement_option(p)
    add_hu_sigma_option(p)
    add_grey_map_options(p)
    p.add_argument(
        "--appendix",
        action="store_true",
        help="add the appendix: the full panoramic, every cross-section, the 3D view, the "
        "engineering detail (calibrations, force terms) and the force curves (by default the "
        "report is the clinical summary)",
    )
    p.add_argument(
        "--timings",
        action="store_true",
        help="print the seconds each stage took (load and compute, pages, PDF) on stderr",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Write the report and say where."""
    from ctdrill.app.commands.options import export_settings
    from ctdrill.app.report.build import Timings, write_report
    from ctdrill.app.text_progress import TextProgress

    settings = export_settings(args)
    progress = TextProgress(sys.stdout, label="report")
    timings = Timings()
    try:
        path, n_pages = write_report(
            args.dicom,
            args.plan,
            args.out,
            settings,
            progress=progress,
            timings=timings,
            appendix=args.appendix,
        )
    finally:
        progress.close()
    sys.stdout.write(f"wrote {path} ({n_pages} pages)\n")
    if args.timings:
        sys.stderr.write(f"report timings: {timings.line()}\n")
    return 0
