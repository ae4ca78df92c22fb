"""Options several commands share, defined once (standard library and numpy-free rules only:
``--help`` stays light)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from ctdrill.imaging.stack import GAP_FACTOR

if TYPE_CHECKING:
    from ctdrill.engine.settings import ExportSettings
    from ctdrill.imaging.plan.implants import ImplantSpec


def add_plan_option(parser: argparse.ArgumentParser, *, required: bool) -> None:
    """``--plan PLAN...``: repeatable; files and folders merge into one plan."""
    parser.add_argument(
        "--plan",
        type=Path,
        required=required,
        nargs="+",
        action="extend",
        metavar="PLAN",
        help="ctdrill-plan/1 JSON, 3D Slicer .mrk.json or segmentation (.seg.nrrd, .nrrd, "
        ".nii.gz, DICOM SEG); repeatable, or a folder: all merge into one plan",
    )
    parser.add_argument(
        "--key",
        type=Path,
        default=None,
        metavar="FILE",
        help="the instructor's key (ctdrill exercise --key) of a blind trial: run on the "
        "trial's plan or CT, which is refused without it (docs/exercises.md)",
    )


#: What ``--ct`` takes, for the commands' help.
CT_HELP = (
    "the CT: a DICOM folder or file, or a NIfTI (.nii, .nii.gz), NRRD (.nrrd, .nhdr) or "
    "MetaImage (.mha, .mhd) file, its type read from the content (--dicom is the same option)"
)


class OneCt(argparse.Action):
    """Stores the CT; a second, different one (``--dicom A --ct B``) is refused, not the last
    silently taken."""

    def __call__(
        self,
        parser: argparse.ArgumentParser,
        namespace: argparse.Namespace,
        values: object,
        option_string: str | None = None,
    ) -> None:
        earlier = getattr(namespace, self.dest, None)
        if earlier is not None and earlier != values:
            parser.error(
                f"{option_string} {values}: the CT is already given ({earlier}); give one CT "
                "(--ct and --dicom are the same option)"
            )
        setattr(namespace, self.dest, values)


def add_ct_option(parser: argparse.ArgumentParser, *, required: bool) -> None:
    """``--ct PATH`` (and its older name ``--dicom``): the CT a command reads (docs/volumes.md)."""
    parser.add_argument(
        "--ct",
        "--dicom",
        dest="dicom",
        action=OneCt,
        type=Path,
        required=required,
        metavar="PATH",
        help=CT_HELP,
    )


def add_series_option(parser: argparse.ArgumentParser) -> None:
    """``--series UID|HASH``: which series of a folder holding several to load."""
    parser.add_argument(
        "--series",
        default=None,
        metavar="UID|HASH",
        help="series to load: its SeriesInstanceUID or the hash outputs print (8+ hex digits)",
    )


def add_override_options(parser: argparse.ArgumentParser) -> None:
    """``--calibration NAME|PATH`` and ``--feed-mm-s``: override every plan's own."""
    parser.add_argument(
        "--calibration",
        default=None,
        metavar="NAME|PATH",
        help="calibration set overriding the plans' (name in assets/calibration or a JSON path)",
    )
    parser.add_argument("--feed-mm-s", type=float, default=None, help="feed overriding the plans'")


def add_interpolate_gaps_option(parser: argparse.ArgumentParser) -> None:
    """``--interpolate-gaps``: interpolate across gaps the drill crosses, stated in the output."""
    parser.add_argument(
        "--interpolate-gaps",
        action="store_true",
        help=f"interpolate HU across slice gaps (steps over {GAP_FACTOR:g} x the nominal slice "
        "step) the "
        "drill crosses, instead of refusing; summary.json then states them (interpolated_gaps) "
        "with warning gap_interpolated",
    )


def add_placement_option(parser: argparse.ArgumentParser) -> None:
    """``--placement MODE``: how the implants will be placed (the margin budget's error)."""
    from ctdrill.imaging.plan.budget import DEFAULT_PLACEMENT, PLACEMENTS

    parser.add_argument(
        "--placement",
        choices=PLACEMENTS,
        default=None,
        help="how the implants will be placed, for the margin budget (the 95th percentile of "
        "placement, canal and CT errors; docs/margin_budget.md): overrides each plan's "
        f"placement key (default: the plan's, else {DEFAULT_PLACEMENT})",
    )


def add_hu_sigma_option(parser: argparse.ArgumentParser) -> None:
    """``--hu-sigma HU``: an HU uncertainty of the series, entered into the force band."""
    parser.add_argument(
        "--hu-sigma",
        type=float,
        default=None,
        metavar="HU",
        help="standard deviation of the series' HU calibration (an offset shared by the whole "
        "scan), combined with the calibration set's covariance in the force band; recorded "
        "in the summary (default: not known, not included)",
    )


def add_grey_map_options(parser: argparse.ArgumentParser) -> None:
    """``--grey-to-hu`` / ``--grey-ref``: map CBCT grey values to HU (docs/export.md)."""
    parser.add_argument(
        "--grey-to-hu",
        default=None,
        metavar="SLOPE,INTERCEPT[,SLOPE_SE,INTERCEPT_SE]",
        help="the series holds grey values, not HU: HU = SLOPE x grey + INTERCEPT, with the "
        "standard errors when known (they enter the force band); recorded in every output",
    )
    parser.add_argument(
        "--grey-ref",
        action="append",
        default=None,
        metavar="X,Y,Z,R=HU",
        help="a region of known HU for the grey-to-HU map: the voxels within R mm of the LPS "
        "point X,Y,Z (e.g. air -1000, a reference insert); give two or more; the line "
        "through their mean grey values is the map, their grey SDs its uncertainty",
    )


def add_implants_option(parser: argparse.ArgumentParser) -> None:
    """``--implants FILE``: a ``ctdrill-implants/1`` file extending the generic library."""
    parser.add_argument(
        "--implants",
        type=Path,
        metavar="FILE",
        help="a ctdrill-implants/1 file of your implants: it extends the generic library "
        "(assets/implants/generic.json), an entry named as a library one replaces it "
        "(docs/plan.md)",
    )


def pick_implant(name: str, implants_file: Path | None) -> ImplantSpec:
    """The implant ``name`` of the library (extended by ``implants_file``); an unknown name is
    an input error listing the names there are."""
    from ctdrill.app.errors import AppInputError
    from ctdrill.imaging.plan.implants import load_implant_library

    library = load_implant_library(implants_file)
    for spec in library:
        if spec.name == name:
            return spec
    raise AppInputError(
        f"--implant {name!r}: no implant of that name in the library; choose one of "
        + ", ".join(repr(s.name) for s in library)
    )


def export_settings(args: argparse.Namespace) -> ExportSettings:
    """The :class:`~ctdrill.engine.settings.ExportSettings` of the export options a command
    parsed (those it does not have: their defaults)."""
    from ctdrill.app.grey_option import parse_grey_options
    from ctdrill.engine.settings import DEFAULTS, ExportSettings

    opts = vars(args)
    return ExportSettings(
        calibration=opts.get("calibration"),
        feed_mm_s=opts.get("feed_mm_s"),
        rate_hz=opts.get("rate_hz", DEFAULTS.rate_hz),
        series=opts.get("series"),
        include_phi=bool(opts.get("include_phi", False)),
        interpolate_gaps=bool(opts.get("interpolate_gaps", False)),
        hu_sigma=opts.get("hu_sigma"),
        grey=parse_grey_options(opts.get("grey_to_hu"), opts.get("grey_ref")),
        plot=not opts.get("no_plot", False),
        per_trajectory=bool(opts.get("per_trajectory", False)),
        placement=opts.get("placement"),
    )
