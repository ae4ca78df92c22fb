"""``ctdrill class report``: a class's grades, confusion matrices and dashboard."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any


def register(subparsers: Any) -> None:
    """Add the ``class`` subcommand."""
    p = subparsers.add_parser(
        "class",
        help="a class's grades, bone-quality confusion matrices and dashboard",
        description="Report on a class (its class file, ctdrill-class/1) from a trainee record.",
    )
    sub = p.add_subparsers(dest="class_command", metavar="ACTION", parser_class=type(p))
    sub.required = True
    r = sub.add_parser(
        "report",
        help="write grades.csv, confusion.csv and the dashboard",
        description=(
            "Write DIR/grades.csv (one row per trainee and exercise: attempts, best, last, "
            "passed), DIR/confusion.csv (the bone-quality exercise per trainee and for the "
            "class) and DIR/dashboard.png and .pdf (score histograms per exercise, learning "
            "curves, the confusion matrix), replacing DIR whole. docs/exercises.md."
        ),
    )
    r.add_argument("--db", type=Path, required=True, metavar="DB", help="the class's record")
    r.add_argument(
        "--class",
        dest="class_file",
        type=Path,
        required=True,
        metavar="FILE",
        help="the class file (ctdrill-class/1)",
    )
    r.add_argument("--out", type=Path, required=True, metavar="DIR", help="output folder")
    r.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Write the report; print where."""
    from ctdrill.app.classroom.report import write_class_report

    files = write_class_report(args.db, args.class_file, args.out)
    sys.stdout.write(f"wrote {', '.join(str(f) for f in files)}\n")
    return 0
