"""``ctdrill phantom OUT``: write the synthetic mandible phantom (DICOM, plan, ground truth)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from ctdrill.imaging.phantom.classes import MISCH_CLASSES


def register(subparsers: Any) -> None:
    """Add the ``phantom`` subcommand."""
    p = subparsers.add_parser(
        "phantom",
        help="write a synthetic mandible phantom as a DICOM series with its plan and ground truth",
        description=(
            "Write OUT/ct/ (DICOM CT series), OUT/plan.json (ctdrill-plan/1) and "
            "OUT/ground_truth.json (canal, tissue HU, exact max safe depth)."
        ),
    )
    p.add_argument("out", type=Path, metavar="OUT", help="output folder")
    p.add_argument(
        "--misch",
        default="D2",
        type=str.upper,
        choices=sorted(MISCH_CLASSES),
        help="trabecular bone class (default D2)",
    )
    p.add_argument("--spacing-mm", type=float, default=0.4, help="voxel spacing, mm (0.4)")
    p.add_argument("--noise-hu", type=float, default=0.0, help="Gaussian noise sigma, HU (0)")
    p.add_argument(
        "--metal-streak", action="store_true", help="add a metal insert and its streak artefact"
    )
    p.add_argument("--seed", type=int, default=0, help="noise seed (0)")
    p.add_argument(
        "--partial-volume",
        type=int,
        default=1,
        metavar="N",
        help="average N^3 points per voxel for scanner-like blurred edges (1: exact, hard edges)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Generate and write the phantom; print where it went."""
    from ctdrill.imaging.phantom.io import write_phantom
    from ctdrill.imaging.phantom.mandible import make_mandible_phantom

    phantom = make_mandible_phantom(
        misch=args.misch,
        spacing_mm=args.spacing_mm,
        noise_hu=args.noise_hu,
        metal_streak=args.metal_streak,
        seed=args.seed,
        partial_volume=args.partial_volume,
    )
    case = write_phantom(args.out, phantom)
    s, r, c = phantom.hu.shape
    sys.stdout.write(
        f"wrote {case.ct_dir} ({s} slices of {r}x{c}, {phantom.spacing_mm[0]:g} mm, "
        f"Misch {phantom.misch}), {case.plan_path}, {case.truth_path}\n"
    )
    return 0
