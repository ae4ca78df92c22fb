"""Every warning code ctdrill emits, and what it means: the one registry.

A warning is one :class:`LoadWarning` (``code``, ``message``): the code says what kind of
thing the user must know (this registry, for readers and programs), the message the
particulars (positions, depths, names).
Every room emits from here: the series' load warnings (``imaging``: ``scope`` ``series``, the
codes of ``ctdrill inspect``), what reading a plan found (``plan``) and what a computed path
found (``path``: ``ctdrill.engine.path_warnings``). :data:`WARNING_CODES` of
:mod:`ctdrill.imaging.provenance` and ``docs/warnings.md`` (:func:`markdown`) derive from it;
:class:`~ctdrill.imaging.provenance.LoadWarning` refuses a code that is not here (a bug), and a
test checks every code in the source and in the outputs. Standard library only.

A new warning: one :class:`WarningCode` here, the check that emits it where its rule lives,
and ``python -m ctdrill.warning_codes > docs/warnings.md``.
"""

from __future__ import annotations

from dataclasses import dataclass

#: What a warning is about: the series as loaded, a plan as read, a computed path.
SCOPES = ("series", "plan", "path")


@dataclass(frozen=True)
class WarningCode:
    """One code: its name, what it is about (:data:`SCOPES`), what it means, and how the
    rooms that read warnings treat it.

    Attributes
    ----------
    blocks_suggest : a candidate with this warning is infeasible (``ctdrill suggest``).
    banner : the window's problem banner shows it, at this rank (1 first); None: not shown.
    words : the problem in a few plain words (the banner's heading); None: the code itself.
    slice_spacing : it is about the slices' spacing (a volume resampled to uniform slices no
        longer has it).
    """

    code: str
    scope: str
    meaning: str
    blocks_suggest: bool = False
    banner: int | None = None
    words: str | None = None
    slice_spacing: bool = False


REGISTRY: tuple[WarningCode, ...] = (
    # the series as loaded (ctdrill inspect; DESIGN.md section 4)
    WarningCode(
        "slice_gap",
        "series",
        "slices are missing: a step wider than 1.5 nominal steps between real slices; sampling "
        "uses the true positions, and a drill lip crossing the gap is refused unless asked to "
        "interpolate across it",
        slice_spacing=True,
    ),
    WarningCode(
        "nonuniform_spacing",
        "series",
        "the slice steps differ (irregular but narrower than a gap); sampling uses every "
        "slice's true position",
        slice_spacing=True,
    ),
    WarningCode(
        "gantry_tilt",
        "series",
        "the slices are sheared from their normal (a gantry tilt); the affine keeps the shear",
    ),
    WarningCode(
        "localizer_dropped", "series", "localizer (scout) images were left out of the volume"
    ),
    WarningCode(
        "multiple_series",
        "series",
        "the folder holds several series; the largest CT series was loaded (--series picks one)",
    ),
    WarningCode(
        "duplicate_slice", "series", "identical duplicate slices were left out of the volume"
    ),
    WarningCode(
        "padding",
        "series",
        "pixels outside the scanner's reconstruction field (padding) are marked: they hold no "
        "data, and a drill lip touching them is refused",
    ),
    WarningCode(
        "not_hu",
        "series",
        "the voxel values are not Hounsfield units (a CBCT's grey values): calibrate them to HU "
        "(--grey-to-hu, --grey-ref) before computing forces",
    ),
    WarningCode(
        "lossy_compression",
        "series",
        "the pixels were stored with lossy compression: HU carry compression error",
    ),
    WarningCode(
        "files_skipped", "series", "DICOM files that are not part of a volume were skipped"
    ),
    WarningCode(
        "files_unreadable",
        "series",
        "files in the folder could not be read as DICOM and were skipped",
    ),
    WarningCode(
        "single_slice",
        "series",
        "one slice only: not a volume for the force path (the slice step is taken from "
        "SliceThickness)",
    ),
    WarningCode(
        "coarse_voxels",
        "series",
        "a slice step or thickness above 1.25 mm, or an in-plane spacing above 0.5 mm: "
        "clearances are known only to about half the coarsest sampling",
    ),
    WarningCode(
        "grey_map_on_hu",
        "series",
        "a grey-to-HU map was applied to a series already in HU, as asked: it changes HU that "
        "were right unless the map was meant for these values",
    ),
    WarningCode(
        "qform_sform_differ",
        "series",
        "a NIfTI file's qform and sform place the voxels apart: the sform is used, as nibabel does",
    ),
    # a plan as read
    WarningCode(
        "plan_default",
        "plan",
        "the plan leaves a setting out and the reader filled in its default (said once, as a note)",
    ),
    WarningCode(
        "no_landmarks",
        "plan",
        "the plan has no landmark: no safety margin is enforced, the drill stops only at the "
        "planned depth",
    ),
    WarningCode(
        "markups_skipped",
        "plan",
        "markups of a 3D Slicer file that ctdrill does not use (or without points) were skipped",
    ),
    WarningCode(
        "segment_empty",
        "plan",
        "segments of a segmentation file that hold no voxel were skipped",
    ),
    WarningCode(
        "implants_too_close",
        "plan",
        "two implants of the plan set are closer than the 3 mm kept between implants (the gap "
        "between their platform-wide bodies)",
        banner=5,
        words="implants too close",
    ),
    WarningCode(
        "implant_protocol",
        "plan",
        "a note: the trajectory has an implant and no drills of its own, so it drills the "
        "implant's drilling protocol (its drills in order, each to the apex plus its tip)",
    ),
    WarningCode(
        "final_drill_mismatch",
        "plan",
        "the final drill does not suit the implant: wider than its diameter (no primary "
        "stability) or narrower than both its apex diameter and its diameter less the allowed "
        "undersize (it could not be seated)",
        banner=8,
        words="final drill does not suit the implant",
    ),
    WarningCode(
        "drill_tip_override",
        "plan",
        "a drill's tip length was given and differs from the tip rule's for its diameter and "
        "point angle (docs/plan.md): the override is used for its depth, stop and clearance",
    ),
    WarningCode(
        "drills_reconciled",
        "plan",
        "a trajectory drill gave another tip than its implant's protocol gives the same "
        "diameter: the protocol's tip is used, so the plan never contradicts itself",
    ),
    # a computed path (ctdrill.engine.path_warnings)
    WarningCode(
        "gap_interpolated",
        "path",
        "the drill lip crosses a slice gap, interpolated linearly between the real slices as "
        "asked (--interpolate-gaps)",
    ),
    WarningCode(
        "plan_violates_margin",
        "path",
        "the planned path breaks a landmark's safety margin (the drill stops before it)",
        blocks_suggest=True,
        banner=1,
        words="safety margin",
    ),
    WarningCode(
        "margin_below_clinical",
        "path",
        "a safety margin is below the clinical 2 mm to the nerve canal",
    ),
    WarningCode(
        "plan_other_series",
        "path",
        "the plan records another series than the one loaded: check that they belong together",
    ),
    WarningCode(
        "calibration_illustrative",
        "path",
        "the calibration set is illustrative (not measured on bone): forces show the pattern, "
        "not validated magnitudes",
    ),
    WarningCode(
        "feed_outside_model",
        "path",
        "the feed lies outside the feeds the calibration was measured at (Eq. 19 is "
        "extrapolated), or beyond the feed factor's cap",
    ),
    WarningCode(
        "extrapolated",
        "path",
        "cut lip samples lie outside the calibration's C' range; the force law was clipped to it",
    ),
    WarningCode(
        "implant_beyond_stop",
        "path",
        "the drill stops before the implant's apex: the implant cannot be seated where planned",
    ),
    WarningCode(
        "implant_above_entry",
        "path",
        "the implant is longer than the planned depth: its platform stands above the entry point",
        banner=6,
        words="implant above the entry",
    ),
    WarningCode(
        "implant_violates_margin",
        "path",
        "the implant body at its planned place breaks a landmark's safety margin",
        blocks_suggest=True,
        banner=2,
        words="implant margin",
    ),
    WarningCode(
        "thin_wall",
        "path",
        "the thinnest bone wall around the implant is under the plan's minimum (min_wall_mm)",
        blocks_suggest=True,
        banner=3,
        words="thin bone wall",
    ),
    WarningCode(
        "cortical_perforation",
        "path",
        "part of the implant surface deeper than 1 mm below the platform lies outside the jaw's "
        "envelope (the cortical surface of the bone it sits in; docs/plan.md, Bone walls)",
        blocks_suggest=True,
        banner=4,
        words="cortical perforation",
    ),
    WarningCode(
        "bone_walls_unknown",
        "path",
        "directions around the implant leave the CT before bone ends: the walls there are not "
        "measured (outside the CT is never counted as bone)",
        blocks_suggest=True,
    ),
    WarningCode(
        "out_of_volume",
        "path",
        "the drill leaves the CT volume before the planned depth: it stops where the lip's "
        "data end",
    ),
    WarningCode(
        "margin_below_budget",
        "path",
        "a clearance keeps its margin but is under the margin budget: the 95th percentile of "
        "the placement mode's, the canal's and the CT's errors combined (docs/margin_budget.md)",
        banner=9,
        words="under the margin budget",
    ),
    WarningCode(
        "implant_in_tooth",
        "path",
        "the implant body enters a tooth (CT numbers of enamel, dentin or metal, >= 2000 HU: "
        "teeth are not bone; docs/plan.md, Teeth)",
        blocks_suggest=True,
        banner=10,
        words="implant in a tooth",
    ),
    WarningCode(
        "implant_near_tooth",
        "path",
        "the implant body is closer to a neighbouring tooth than the clinical 1.5 mm",
        banner=11,
        words="implant near a tooth",
    ),
    WarningCode(
        "canal_entry",
        "path",
        "the implant body enters a nerve canal (its apex inside it): named as the canal, not "
        "as a cortical perforation",
        banner=7,
        words="implant in the canal",
    ),
)

#: code -> its entry.
WARNINGS: dict[str, WarningCode] = {w.code: w for w in REGISTRY}


class UnknownWarningCode(LookupError):
    """A code emitted that the registry does not hold (a bug: register it)."""


def check_code(code: str) -> str:
    """``code``, or :class:`UnknownWarningCode` when it is not registered."""
    if code not in WARNINGS:
        raise UnknownWarningCode(
            f"warning code {code!r} is not in ctdrill/warning_codes.py: register it with its "
            "meaning"
        )
    return code


@dataclass(frozen=True)
class LoadWarning:
    """One warning, wherever it arises (a load, a plan as read, a computed path, the verdict):
    the one type every room emits and every output lists as ``{"code", "message"}``.

    Attributes
    ----------
    code : str
        A code of this registry; any other is refused (a bug: register it).
    message : str
        Human-readable detail (positions, depths, names), built from the values it reports.
    """

    code: str
    message: str

    def __post_init__(self) -> None:
        check_code(self.code)


def meaning(code: str) -> str:
    """What ``code`` means."""
    return WARNINGS[check_code(code)].meaning


def codes(scope: str | None = None) -> tuple[str, ...]:
    """Every code (of ``scope``), in the registry's order."""
    return tuple(w.code for w in REGISTRY if scope is None or w.scope == scope)


def blocking_codes() -> tuple[str, ...]:
    """The codes that make a ``suggest`` candidate infeasible, in the registry's order."""
    return tuple(w.code for w in REGISTRY if w.blocks_suggest)


def banner_codes() -> tuple[str, ...]:
    """The codes the window's problem banner shows, by their rank."""
    shown = [w for w in REGISTRY if w.banner is not None]
    return tuple(w.code for w in sorted(shown, key=lambda w: w.banner or 0))


def words(code: str) -> str:
    """``code``'s plain words (the banner's heading), else the code with spaces."""
    entry = WARNINGS[check_code(code)]
    return entry.words if entry.words is not None else code.replace("_", " ")


def slice_spacing_codes() -> frozenset[str]:
    """The codes about the slices' spacing (resampling to uniform slices clears them)."""
    return frozenset(w.code for w in REGISTRY if w.slice_spacing)


_TITLES = {
    "series": "The series as loaded (`ctdrill inspect`, every output)",
    "plan": "A plan as read",
    "path": "A computed path (`summary.json`, the terminal, the report, the window)",
}


def markdown() -> str:
    """``docs/warnings.md``: every code and its meaning, by scope."""
    out = [
        "# Warning codes",
        "",
        "Written by `python -m ctdrill.warning_codes` from `ctdrill/warning_codes.py`, the one",
        "registry (a test checks this page against it). Every output lists warnings as",
        '`{"code", "message"}`: the code says what kind of thing it is, the message the',
        "particulars.",
    ]
    for scope in SCOPES:
        out += ["", f"## {_TITLES[scope]}", "", "| code | meaning |", "| --- | --- |"]
        out += [f"| `{w.code}` | {w.meaning} |" for w in REGISTRY if w.scope == scope]
    return "\n".join(out) + "\n"


if __name__ == "__main__":  # pragma: no cover
    print(markdown(), end="")
