"""``ctdrill panorama``: the panoramic reformat along the arch and a cross-section (headless)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from ctdrill.app.commands.options import (
    add_ct_option,
    add_grey_map_options,
    add_plan_option,
    add_series_option,
)


def register(subparsers: Any) -> None:
    """Add the ``panorama`` subcommand."""
    p = subparsers.add_parser(
        "panorama",
        help="panoramic reformat along the dental arch and a cross-section (PNG + arrays)",
        description=(
            "Sample the CT along the plan's dental arch (arch_mm, or a Slicer Curve named "
            "'arch') into a panoramic reformat, and across the arch through the first "
            "trajectory's axis into a cross-section; draw the canal with its margin zone, the "
            "implant and the drill on both. Writes OUT/panorama.png, panorama.npz, "
            "cross_section.png, cross_section.npz (arrays hu and lps: the LPS mm of each "
            "pixel) and reformat.json (the geometry and options). Samples outside the CT are "
            "-1000 HU. See docs/panorama.md."
        ),
    )
    add_ct_option(p, required=True)
    add_plan_option(p, required=True)
    p.add_argument("--out", type=Path, required=True, metavar="OUT", help="output folder")
    add_series_option(p)
    p.add_argument(
        "--pixel-mm",
        type=float,
        default=None,
        help="pixel size of both images, mm (default: the CT's smallest voxel spacing)",
    )
    p.add_argument(
        "--slab-mm",
        type=float,
        default=10.0,
        help="panorama slab thickness across the arch, mm (default 10; 0: one curved plane)",
    )
    p.add_argument(
        "--slab-mode",
        choices=("mean", "mip"),
        default="mean",
        help="slab average or maximum intensity projection (both images; default mean)",
    )
    p.add_argument(
        "--height-mm",
        type=float,
        default=None,
        help="panorama height, mm, centred on the arch's height (default: the CT's whole "
        "superior-inferior range)",
    )
    p.add_argument(
        "--cs-slab-mm", type=float, default=1.0, help="cross-section slab, mm (default 1)"
    )
    p.add_argument(
        "--cs-size-mm",
        type=float,
        default=40.0,
        help="cross-section width and height, mm (default 40)",
    )
    p.add_argument("--level-hu", type=float, default=None, help="display window level, HU")
    p.add_argument("--width-hu", type=float, default=None, help="display window width, HU")
    add_grey_map_options(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Load, reformat, draw, write; list what was written."""
    from ctdrill.app.errors import AppInputError
    from ctdrill.app.grey_option import parse_grey_options
    from ctdrill.app.reformat.draw import DEFAULT_LEVEL_HU, DEFAULT_WIDTH_HU
    from ctdrill.app.reformat.export import ReformatOptions, export_panorama, finite_or_none
    from ctdrill.engine.grey import map_volume
    from ctdrill.imaging import load_ct
    from ctdrill.imaging.plan.load import load_plan_set

    width_hu = DEFAULT_WIDTH_HU if args.width_hu is None else args.width_hu
    level_hu = DEFAULT_LEVEL_HU if args.level_hu is None else args.level_hu
    if finite_or_none(width_hu, "--width-hu") is None or not abs(level_hu) < 1e6:
        raise AppInputError("--level-hu: give a finite number")
    size = finite_or_none(args.cs_size_mm, "--cs-size-mm")
    options = ReformatOptions(
        pixel_mm=finite_or_none(args.pixel_mm, "--pixel-mm"),
        slab_mm=float(finite_or_none(args.slab_mm, "--slab-mm", zero_ok=True) or 0.0),
        slab_mode=args.slab_mode,
        height_mm=finite_or_none(args.height_mm, "--height-mm"),
        cs_slab_mm=float(finite_or_none(args.cs_slab_mm, "--cs-slab-mm", zero_ok=True) or 0.0),
        cs_width_mm=float(size or 40.0),
        cs_height_mm=float(size or 40.0),
        level_hu=float(level_hu),
        width_hu=float(width_hu),
    )
    grey = parse_grey_options(args.grey_to_hu, args.grey_ref)
    plans = load_plan_set(args.plan)
    volume, _map = map_volume(load_ct(args.dicom, series_uid=args.series), grey)
    written = export_panorama(volume, plans, args.plan, args.out, options)
    for path in written:
        sys.stdout.write(f"wrote {path}\n")
    return 0
