"""``ctdrill plan``: merge plan files (a Slicer case saved one markup per file) and convert."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any


def register(subparsers: Any) -> None:
    """Add the ``plan`` subcommand."""
    p = subparsers.add_parser(
        "plan",
        help="merge plan files and convert between ctdrill-plan/1 and Slicer markups",
        description=(
            "Read plan files (ctdrill-plan/1 JSON, 3D Slicer .mrk.json, segmentations, or a "
            "folder of them), merge them into one plan and write it to OUT: ctdrill-plan/1 "
            "when OUT ends in .json, 3D Slicer markups when it ends in .mrk.json. The plan "
            "must hold one trajectory (a Line)."
        ),
    )
    p.add_argument(
        "plans",
        type=Path,
        nargs="+",
        metavar="PLAN",
        help="plan files or folders (merged; a trajectory or landmark in two files must agree)",
    )
    p.add_argument(
        "--out",
        type=Path,
        required=True,
        metavar="OUT",
        help="the plan to write: NAME.json (ctdrill-plan/1) or NAME.mrk.json (Slicer markups)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Merge, convert, write; print what was written and the plan's warnings."""
    from ctdrill.app.errors import AppInputError
    from ctdrill.imaging.plan.types import load_one_plan, plan_warnings, save_plan

    out: Path = args.out
    if not out.name.lower().endswith(".json"):
        raise AppInputError(
            f"--out {out}: name a .json (ctdrill-plan/1) or .mrk.json (Slicer markups) file"
        )
    if not out.resolve().parent.is_dir():
        raise AppInputError(f"--out {out}: folder {out.resolve().parent} does not exist")
    plan = load_one_plan(args.plans)
    save_plan(plan, out)
    for code, message in plan_warnings(plan):
        sys.stderr.write(
            f"warning: {message}\n" if code != "plan_default" else f"note: {message}\n"
        )
    kind = "3D Slicer markups" if out.name.lower().endswith(".mrk.json") else "ctdrill-plan/1"
    sys.stdout.write(
        f"wrote {out} ({kind}): trajectory {plan.name!r}, {len(plan.landmarks)} landmarks\n"
    )
    return 0
