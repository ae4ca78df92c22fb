"""``ctdrill demo``: export the bundled mandible phantom and say what was written."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any


def register(subparsers: Any) -> None:
    """Add the ``demo`` subcommand."""
    p = subparsers.add_parser(
        "demo",
        help="export the bundled mandible phantom (force, HU, clearance, plot)",
        description=(
            "Run the headless export on the bundled phantom case (assets/demo/ct with "
            "assets/demo/plan.json) into a fresh folder."
        ),
    )
    p.add_argument(
        "--out",
        type=Path,
        default=Path("demo-out"),
        metavar="DIR",
        help="output folder (default demo-out/; a non-empty folder is refused unless a "
        "previous demo made it)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Export the demo and list the files with what each holds."""
    import json

    from ctdrill.app.export_demo import DEMO_DIR, run_demo
    from ctdrill.app.summary_lines import summary_lines
    from ctdrill.engine.summary import read_summary

    written = run_demo(args.out)
    about = {
        "force.csv": "force time series at constant feed until the stop depth",
        "profile.csv": "HU, cut fraction, force terms, clearance and Misch class per depth",
        "summary.json": "stop depth and reason, clearance, calibration, HU grading, warnings",
        "force.png": "force, HU (Misch bands) and clearance against depth",
    }
    sys.stdout.write(f"demo: {DEMO_DIR / 'ct'} with {DEMO_DIR / 'plan.json'}\n")
    for path in written:
        sys.stdout.write(f"wrote {path}  ({about.get(path.name, '')})\n")
    summary = read_summary(
        json.loads((Path(args.out) / "summary.json").read_text(encoding="utf-8"))
    )
    # The same stop, calibration and warning lines as ``ctdrill export``.
    sys.stdout.write("".join(line + "\n" for line in summary_lines(summary)))
    return 0
