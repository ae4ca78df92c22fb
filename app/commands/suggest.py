"""``ctdrill suggest``: candidate axes around a planned one, ranked by bone engagement under
the safety margins (docs/suggest.md)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from ctdrill.app.commands.options import (
    add_ct_option,
    add_implants_option,
    add_interpolate_gaps_option,
    add_plan_option,
    add_series_option,
)


def _weights(text: str) -> tuple[float, float, float]:
    parts = text.split(",")
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        values = ()
    if len(values) != 3:
        raise argparse.ArgumentTypeError(
            f"expected three numbers BODY,CREST,APEX (e.g. 1,0.5,0.5), got {text!r}"
        )
    return values[0], values[1], values[2]


def register(subparsers: Any) -> None:
    """Add the ``suggest`` subcommand."""
    from ctdrill.app.search.defaults import (
        DEFAULT_CONE_DEG,
        DEFAULT_COUNT,
        DEFAULT_RADIUS_MM,
        DEFAULT_WEIGHTS,
    )

    p = subparsers.add_parser(
        "suggest",
        help="suggest a nearby axis meeting better bone while keeping every margin and bone wall",
        description=(
            "Sample candidate axes around the planned one (entry moved within --radius-mm on "
            "the bone surface, axis tilted within --cone-deg, same drills, implant and planned "
            "depth), score the bone around the implant body (mean HU on a shell just outside "
            "its surface, cortical contact at its neck and apex) and keep only those whose "
            "implant and every drill keep each landmark's margin with no thin bone wall and "
            "no cortical perforation (checked exactly on the best-ranked candidates). "
            "Writes OUT/candidates.csv (every candidate, "
            "best first; candidate 0 is the planned axis), OUT/suggest.json and, when a "
            "candidate is feasible, OUT/best.plan.json (the plan with the best axis); when "
            "none is, OUT/alternatives.csv (the library's shorter or narrower implants at the "
            "same site, checked by the same rule). See docs/suggest.md."
        ),
    )
    add_ct_option(p, required=True)
    add_plan_option(p, required=True)
    p.add_argument("--out", type=Path, required=True, metavar="OUT", help="output folder")
    p.add_argument(
        "--trajectory",
        type=int,
        default=1,
        metavar="N",
        help="which trajectory of the plan files to search around, 1-based in the order "
        "`ctdrill export` lists them (default 1)",
    )
    p.add_argument(
        "--radius-mm",
        type=float,
        default=DEFAULT_RADIUS_MM,
        help="largest entry move, in the plane across the planned axis (default "
        f"{DEFAULT_RADIUS_MM:g})",
    )
    p.add_argument(
        "--cone-deg",
        type=float,
        default=DEFAULT_CONE_DEG,
        help=f"largest tilt from the planned axis, degrees (default {DEFAULT_CONE_DEG:g})",
    )
    p.add_argument(
        "--count",
        type=int,
        default=DEFAULT_COUNT,
        help=f"candidates in all, the planned axis included (default {DEFAULT_COUNT})",
    )
    p.add_argument(
        "--seed",
        type=int,
        default=None,
        help="shift the (deterministic) Halton sample by a random vector of this seed",
    )
    p.add_argument(
        "--weights",
        type=_weights,
        default=DEFAULT_WEIGHTS,
        metavar="BODY,CREST,APEX",
        help="weights of the score terms (default "
        + ",".join(f"{w:g}" for w in DEFAULT_WEIGHTS)
        + ")",
    )
    add_series_option(p)
    add_interpolate_gaps_option(p)
    add_implants_option(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Search, write, and say what was found."""
    from ctdrill.app.search.candidates import SearchSpace, SuggestInputError
    from ctdrill.app.search.score import Objective
    from ctdrill.app.search.suggest import suggest
    from ctdrill.app.search.suggest_write import (
        alternative_lines,
        summary_lines,
        write_suggestion,
    )
    from ctdrill.app.search.warmup import SLOW_PATH_NOTE, kernels_ready
    from ctdrill.engine.plans import plan_calibration
    from ctdrill.imaging import load_ct
    from ctdrill.imaging.plan.load import load_plan_set

    space = SearchSpace(
        radius_mm=args.radius_mm, cone_deg=args.cone_deg, count=args.count, seed=args.seed
    )
    body, crest, apex = args.weights
    objective = Objective(body_weight=body, crest_weight=crest, apex_weight=apex)
    plans = load_plan_set(args.plan)
    if not 1 <= args.trajectory <= len(plans):
        names = ", ".join(f"{i + 1}: {p.name!r}" for i, p in enumerate(plans))
        raise SuggestInputError(
            f"--trajectory {args.trajectory}: the plan files hold {len(plans)} "
            f"trajectories ({names}); give a number from 1 to {len(plans)}"
        )
    plan = plans[args.trajectory - 1]
    calibration = plan_calibration(plan)
    volume = load_ct(args.dicom, series_uid=args.series)
    result = suggest(
        volume, plan, calibration, space, objective, interpolate_gaps=args.interpolate_gaps
    )
    alts = None
    if result.best_index is None and plan.implant is not None:
        from ctdrill.app.search.alternatives import alternatives
        from ctdrill.imaging.plan.implants import load_implant_library

        alts = alternatives(volume, plan, load_implant_library(args.implants))
    written = write_suggestion(result, args.out, alts)
    if not kernels_ready():
        sys.stdout.write(SLOW_PATH_NOTE + "\n")
    for path in written:
        sys.stdout.write(f"wrote {path}\n")
    lines = summary_lines(result) + ([] if alts is None else alternative_lines(alts))
    sys.stdout.write("".join(line + "\n" for line in lines))
    return 0
