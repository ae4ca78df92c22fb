"""``ctdrill exercise``: exercises that train the feel for bone (docs/exercises.md)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any


def register(subparsers: Any) -> None:
    """Add the ``exercise`` subcommand and its exercises."""
    p = subparsers.add_parser(
        "exercise",
        help="write blind bone-quality trials; list the stop-yourself exercise's aid levels",
        description="Exercises that train the feel for bone (docs/exercises.md).",
    )
    sub = p.add_subparsers(dest="exercise", metavar="EXERCISE", parser_class=type(p))
    sub.required = True
    bq = sub.add_parser(
        "bone-quality",
        help="write N blind trials of Misch class D1-D4 to drill and name",
        description=(
            "Write OUT/trial-01 ... OUT/trial-N, each a site to drill (ct/, plan.json with the "
            "calibration pinned, trial.json with the class sealed): phantoms from the shipped "
            "generator and, with --ct and --plan, regions of a real CT. Nothing a trainee "
            "opens names the class. Drill a trial with ctdrill rehearse --ct OUT/trial-01/ct "
            "--plan OUT/trial-01/plan.json ..., then name it: ctdrill assess SESSION --answer "
            "CLASS --db FILE --trainee ID."
        ),
    )
    bq.add_argument("--out", type=Path, required=True, metavar="DIR", help="the trials' folder")
    bq.add_argument("--trials", type=int, required=True, metavar="N", help="how many (1-99)")
    bq.add_argument("--seed", type=int, required=True, metavar="K", help="the exercise's seed")
    bq.add_argument(
        "--calibration",
        default="bone-illustrative",
        metavar="NAME",
        help="calibration set pinned in every trial (default bone-illustrative)",
    )
    bq.add_argument(
        "--spacing-mm", type=float, default=0.4, help="the phantoms' voxel spacing, mm (0.4)"
    )
    bq.add_argument("--ct", type=Path, default=None, help="a real CT whose sites become trials")
    bq.add_argument(
        "--plan",
        type=Path,
        action="append",
        default=[],
        help="a site on --ct (a plan file; repeatable): its region is one trial",
    )
    bq.add_argument(
        "--key",
        type=Path,
        default=None,
        metavar="FILE",
        help="write the instructor's plain key here (outside DIR)",
    )
    bq.set_defaults(func=run_bone_quality)
    sy = sub.add_parser(
        "stop-yourself",
        help="list the stop-yourself exercise's aid levels, from all aids to none",
        description=(
            "The stop-yourself exercise fades the aids level by level; each level is an "
            "exercise with a pass mark (ctdrill rehearse --aids LEVEL, the window's aid menu, "
            "a class file's aid_level)."
        ),
    )
    sy.set_defaults(func=run_stop_yourself)


def run_bone_quality(args: argparse.Namespace) -> int:
    """Write the trials; print where (never their classes)."""
    from ctdrill.app.errors import AppInputError
    from ctdrill.app.exercise.bone_quality import RealSite, write_bone_quality

    if args.plan and args.ct is None:
        raise AppInputError("--plan names a site on a real CT: give --ct too")
    if args.ct is not None and not args.plan:
        raise AppInputError("--ct: give the sites on it with --plan (repeatable)")
    sites = [RealSite(args.ct, p) for p in args.plan]
    trials = write_bone_quality(
        args.out,
        trials=args.trials,
        seed=args.seed,
        calibration=args.calibration,
        spacing_mm=args.spacing_mm,
        sites=sites,
        key_path=args.key,
    )
    real = sum(t.source != "phantom" for t in trials)
    sys.stdout.write(
        f"wrote {len(trials)} blind trials in {args.out} ({real} from a real CT), exercise "
        f"{trials[0].card.exercise_id}"
        + (f"; the key in {args.key}" if args.key is not None else "")
        + "\n"
    )
    return 0


def run_stop_yourself(args: argparse.Namespace) -> int:
    """Print the aid levels."""
    from ctdrill.app.exercise.aids import AID_LEVELS

    for level in AID_LEVELS:
        sys.stdout.write(f"{level.name}: {level.describe()} (pass mark {level.pass_mark:g})\n")
    return 0
