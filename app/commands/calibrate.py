"""``ctdrill calibrate MANIFEST.csv``: fit a calibration set to slave-robot force recordings."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ctdrill.app.errors import AppInputError
from ctdrill.model.fit_defaults import DEFAULT_DEPTH_WINDOW_MM

if TYPE_CHECKING:
    from ctdrill.model.fit import CalibrationFit


def register(subparsers: Any) -> None:
    """Add the ``calibrate`` subcommand."""
    p = subparsers.add_parser(
        "calibrate",
        help="fit a calibration set (Eq. 13) to force recordings",
        description=(
            "Fit the force law log10 F = b0 + log10(1 + Ke v) + n log10(HU + 1000) to slave-robot "
            "recordings listed in MANIFEST.csv (columns file, hu, feed_mm_s; paths relative to "
            "it). Each recording (columns time_s, position_mm, force_n) gives A0 (DC) and the "
            "amplitudes at k * blades * rpm / 60 Hz by a Hann-windowed DFT over its depth window. "
            "With --literature instead of a manifest, fit the bone-literature set to published "
            "points (bone_force_points.csv; docs/model.md says which points and conversions)."
        ),
    )
    p.add_argument(
        "manifest", type=Path, nargs="?", metavar="MANIFEST.csv", help="recordings manifest"
    )
    p.add_argument(
        "--literature",
        type=Path,
        default=None,
        metavar="CSV",
        help="fit bone-literature to this bone_force_points.csv instead of recordings",
    )
    p.add_argument("--rpm", type=float, default=None, help="drill speed, rev/min (recordings)")
    p.add_argument(
        "--blades", type=int, default=None, help="cutting blades of the drill (recordings)"
    )
    p.add_argument("--out", type=Path, required=True, metavar="CAL.json", help="output set")
    p.add_argument("--name", default=None, help="set name (default: the manifest's stem)")
    p.add_argument("--material", default="unspecified", help="material cut in the recordings")
    p.add_argument(
        "--gate-hu", type=float, default=None, help="gate centre, HU (default: nearest bundled set)"
    )
    p.add_argument("--gate-width-hu", type=float, default=None, help="gate width, HU")
    p.add_argument(
        "--ke",
        type=float,
        default=None,
        metavar="PER_MM_S",
        help="hold Ke at this value instead of fitting it (needed when all feeds are equal)",
    )
    p.add_argument(
        "--depth-window-mm",
        type=float,
        nargs=2,
        default=list(DEFAULT_DEPTH_WINDOW_MM),
        metavar=("LO", "HI"),
        help="depths (position_mm) of full cutting to analyse (default: 1 8, as the paper)",
    )
    p.add_argument(
        "--orders",
        type=int,
        nargs="+",
        default=[1, 2],
        help="harmonic orders to fit (default: 1 2, i.e. 30 and 60 Hz for 2 blades at 900 rpm)",
    )
    p.set_defaults(func=run)


def format_fit(fit: CalibrationFit) -> str:
    """A Table 2-3 style summary: parameter, value, standard error in %."""
    lines = [f"calibration {fit.calibration.name}: {len(fit.measurements)} recordings"]
    lines.append(f"{'parameter':<20} {'value':>10} {'error (%)':>10}")
    for key, p in fit.parameters.items():
        pct = "-" if p.stderr_pct is None or p.stderr == 0.0 else f"{p.stderr_pct:.2f}"
        lines.append(f"{key:<20} {p.value:>10.4g} {pct:>10}")
    lo, hi = fit.calibration.c_prime_range
    lines.append(f"valid for C' = HU + 1000 in [{lo:g}, {hi:g}]")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Fit, write the set, check it loads, print the summary."""
    from ctdrill.app.records import atomic_write_text
    from ctdrill.model.calibration import calibration_from_dict
    from ctdrill.model.fit import calibrate_from_manifest, fit_document

    if args.out.exists() and args.out.is_dir():
        raise AppInputError(f"--out {args.out}: is a folder; give a .json file path")
    if (args.manifest is None) == (args.literature is None):
        raise AppInputError("give either MANIFEST.csv (recordings) or --literature CSV, not both")
    if args.literature is not None:
        return _run_literature(args)
    if args.rpm is None or args.blades is None:
        raise AppInputError("--rpm and --blades are required with MANIFEST.csv")
    fit = calibrate_from_manifest(
        args.manifest,
        rpm=args.rpm,
        blades=args.blades,
        name=args.name,
        material=args.material,
        orders=tuple(args.orders),
        gate_hu=args.gate_hu,
        gate_width_hu=args.gate_width_hu,
        ke_per_mm_s=args.ke,
        depth_window_mm=(args.depth_window_mm[0], args.depth_window_mm[1]),
    )
    text = json.dumps(fit_document(fit), indent=2) + "\n"
    # what we write must load: check the document before it replaces anything
    calibration_from_dict(json.loads(text), source_path=args.out)
    # a temporary sibling renamed over --out: a full disk or a kill leaves the old set whole
    atomic_write_text(args.out, text, what="--out")
    sys.stdout.write(format_fit(fit) + f"\nwrote {args.out}\n")
    return 0


def format_literature(doc: dict[str, Any]) -> str:
    """Parameter, value and standard error of the literature fit, and the points used."""
    lines = [f"calibration {doc['name']}: {doc['provenance']['method']}"]
    lines.append(f"{'parameter':<10} {'value':>10} {'stderr':>10} {'error (%)':>10}")
    for key, p in doc["fit"].items():
        lines.append(f"{key:<10} {p['value']:>10.4g} {p['stderr']:>10.3g} {p['stderr_pct']:>10.2f}")
    used = ", ".join(p["source_key"] for p in doc["provenance"]["points_used"])
    lines.append(f"points used: {used}")
    lines.append(
        f"points excluded: {len(doc['provenance']['points_excluded'])} (reasons in the set)"
    )
    return "\n".join(lines)


def _run_literature(args: argparse.Namespace) -> int:
    from ctdrill.app.records import atomic_write_text
    from ctdrill.imaging.misch import BONE_HU, MISCH_BANDS_HU
    from ctdrill.model.calibration import calibration_from_dict
    from ctdrill.model.literature import fit_literature

    # the bands and the bone edge are imaging's (imaging/misch.py); the model takes them here
    doc = fit_literature(args.literature, bands_hu=MISCH_BANDS_HU, gate_hu=BONE_HU)
    text = json.dumps(doc, indent=2, ensure_ascii=False) + "\n"
    calibration_from_dict(json.loads(text), source_path=args.out)
    atomic_write_text(args.out, text, what="--out")
    sys.stdout.write(format_literature(doc) + f"\nwrote {args.out}\n")
    return 0
