"""``ctdrill plan``: merge plan files (a Slicer case saved one markup per file) and convert."""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

from ctdrill.app.commands.options import add_implants_option, pick_implant


def register(subparsers: Any) -> None:
    """Add the ``plan`` subcommand."""
    p = subparsers.add_parser(
        "plan",
        help="merge plan files and convert between ctdrill-plan/1 and Slicer markups",
        description=(
            "Read plan files (ctdrill-plan/1 JSON, 3D Slicer .mrk.json, segmentations, or a "
            "folder of them), merge them into one plan and write it to OUT: 3D Slicer markups "
            "when OUT ends in .mrk.json, else ctdrill-plan/1 (OUT.json when OUT has no .json "
            "ending: OUT may be a stem). Every "
            "trajectory (Line) of the inputs is written: one in ctdrill-plan/1's single form, "
            "several in its trajectories list (one Line each in markups), with the shared "
            "landmarks and dental arch."
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
        help="the plan to write: NAME.json or NAME (ctdrill-plan/1, written as NAME.json), "
        "NAME.mrk.json or NAME.mrk (3D Slicer markups, written as NAME.mrk.json)",
    )
    p.add_argument(
        "--implant",
        metavar="NAME",
        help="place this library implant on every trajectory (apex at the target); "
        "replaces any implant the plan gives",
    )
    add_implants_option(p)
    p.set_defaults(func=run)


def plan_out_path(out: Path) -> Path:
    """The file ``--out`` names: itself when it ends in ``.json``; a stem (no suffix, or
    ``.mrk``) gets ``.json`` (``NAME.mrk`` becomes the Slicer markups ``NAME.mrk.json``); any
    other suffix is refused."""
    from ctdrill.app.errors import AppInputError

    name = out.name.lower()
    if name.endswith(".json"):
        return out
    if out.suffix == "" or name.endswith(".mrk"):
        return out.with_name(out.name + ".json")
    raise AppInputError(
        f"--out {out}: name a .json (ctdrill-plan/1) or .mrk.json (Slicer markups) file, or a "
        "stem without a suffix (written as STEM.json)"
    )


def run(args: argparse.Namespace) -> int:
    """Merge, convert, write; print what was written and the plan's warnings (those the plan
    alone shows: ``implant_above_entry``, ``implants_too_close`` among them)."""
    from ctdrill.app.errors import AppInputError
    from ctdrill.imaging.plan.load import load_plan_set
    from ctdrill.imaging.plan.types import plan_warnings
    from ctdrill.imaging.plan.write import write_plans

    out = plan_out_path(args.out)
    if out.is_dir():
        raise AppInputError(f"--out {args.out}: {out} is a folder; name the plan file")
    if not out.resolve().parent.is_dir():
        raise AppInputError(f"--out {out}: folder {out.resolve().parent} does not exist")
    plans = load_plan_set(args.plans)
    if args.implants is not None and args.implant is None:
        raise AppInputError("--implants: give --implant NAME too (the implant to place)")
    if args.implant is not None:
        spec = pick_implant(args.implant, args.implants)
        plans = tuple(replace(p, implant=spec) for p in plans)
    write_plans(plans, out)
    from ctdrill.imaging.plan.implant_checks import implant_warnings, implants_too_close
    from ctdrill.warning_codes import LoadWarning

    # What the plan alone shows (no CT: the stop is not known, so not implant_beyond_stop).
    pairs = implants_too_close(plans)
    seen: set[LoadWarning] = set()
    for plan in plans:
        found = [
            *plan_warnings(plan),
            *implant_warnings(plan, plan.planned_depth_mm, "planned_depth"),
            *pairs.get(plan.name, ()),
        ]
        for w in found:
            if w in seen:
                continue
            seen.add(w)
            sys.stderr.write(
                f"warning: {w.message}\n" if w.code != "plan_default" else f"note: {w.message}\n"
            )
    kind = "3D Slicer markups" if out.name.lower().endswith(".mrk.json") else "ctdrill-plan/1"
    first = plans[0]
    names = ", ".join(repr(p.name) for p in plans)
    what = f"trajectory {names}" if len(plans) == 1 else f"{len(plans)} trajectories ({names})"
    extra = "" if first.arch_lps is None else ", the dental arch"
    implants = sum(p.implant is not None for p in plans)
    extra += f", {implants} implant{'s' if implants != 1 else ''}" if implants else ""
    sys.stdout.write(f"wrote {out} ({kind}): {what}, {len(first.landmarks)} landmarks{extra}\n")
    return 0
