"""Loading plans: plan files, 3D Slicer markups and segmentations, read, merged, validated.

The entry points every command, the GUI and :mod:`ctdrill.api` use: :func:`load_plan`,
:func:`load_plans`, :func:`load_plan_set` and :func:`load_one_plan`. The formats are described in
:mod:`ctdrill.imaging.plan.types`; this module dispatches each file to its reader
(:mod:`~ctdrill.imaging.plan.plan_file`, :mod:`~ctdrill.imaging.plan.slicer`,
:mod:`~ctdrill.imaging.plan.segmentation`) and merges the parts
(:mod:`~ctdrill.imaging.plan.merge`). It sits above the value types: nothing below it reads a
plan file.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from ctdrill.imaging.plan.merge import merge_parts
from ctdrill.imaging.plan.plan_file import parse_ctdrill
from ctdrill.imaging.plan.read import PlanParts, _Ctx, _read_json
from ctdrill.imaging.plan.slicer import parse_slicer
from ctdrill.imaging.plan.types import MAX_TRAJECTORIES, PLAN_FORMAT, Plan, PlanInputError
from ctdrill.numtext import ascii_whole

#: Segmentation files a folder contributes (plain ``.nrrd`` is not taken from a folder: Slicer
#: saves volumes, the CT itself included, as ``.nrrd``).
FOLDER_SEGMENTATIONS = (".seg.nrrd",)
#: Label files accepted when named explicitly.
LABEL_SUFFIXES = (".seg.nrrd", ".nrrd", ".nhdr", ".nii.gz", ".nii", ".mha", ".mhd", ".dcm")


def _lower(path: Path) -> str:
    return path.name.lower()


def read_parts(path: str | os.PathLike[str]) -> PlanParts:
    """Read one plan file's trajectories and landmarks, converted to LPS and validated.

    A ``ctdrill-plan/1`` file holds one trajectory (or several in ``trajectories``), its
    landmarks and arch; a Slicer ``.mrk.json``
    holds any number of Line markups (trajectories) and Curve/Fiducial markups (landmarks),
    possibly none of either (3D Slicer saves one markup per file).

    Raises
    ------
    PlanInputError
        Naming the file and the field path (``plan.json: drill.diameter_mm must be ...``).
    """
    p = Path(path)
    ctx = _Ctx(p)
    doc = _read_json(p)
    if not isinstance(doc, dict):
        raise ctx.fail("(top level)", "must be a JSON object", type(doc).__name__)
    if "markups" in doc and "format" not in doc:
        return parse_slicer(ctx, doc)
    if "format" not in doc:
        raise ctx.fail(
            "format",
            f'is missing; a plan starts with "format": "{PLAN_FORMAT}" '
            "(or is a 3D Slicer .mrk.json with markups)",
        )
    return parse_ctdrill(ctx, doc)


def plan_inputs(paths: Sequence[str | os.PathLike[str]]) -> list[Path]:
    """The files named by ``paths``: files as given, folders expanded (their ``*.json`` /
    ``*.mrk.json`` and :data:`FOLDER_SEGMENTATIONS` files, sorted by name)."""
    out: list[Path] = []
    for raw in paths:
        p = Path(raw)
        if p.is_dir():
            found = sorted(
                q
                for q in p.iterdir()
                if q.is_file()
                and (_lower(q).endswith(".json") or _lower(q).endswith(FOLDER_SEGMENTATIONS))
            )
            if not found:
                raise PlanInputError(
                    f"{p}: the folder holds no plan file (.json, .mrk.json) or segmentation "
                    "(.seg.nrrd); name the plan files"
                )
            out.extend(found)
        else:
            out.append(p)
    return out


def read_input(path: Path) -> PlanParts:
    """One input file's parts: a plan file, or a segmentation/labelmap file of landmarks."""
    if _lower(path).endswith(LABEL_SUFFIXES) and not _lower(path).endswith(".json"):
        from ctdrill.imaging.plan.segmentation import segmentation_parts  # nibabel, pynrrd

        return segmentation_parts(path)
    return read_parts(path)


def load_plans(path: str | os.PathLike[str]) -> tuple[Plan, ...]:
    """Read every trajectory of a plan file, converted to LPS and validated.

    A ``ctdrill-plan/1`` file holds one trajectory, or several in ``trajectories``; a Slicer
    ``.mrk.json`` holds one per Line markup (all sharing the file's landmarks and arch). A file
    without a trajectory is refused.

    Raises
    ------
    PlanInputError
        Naming the file and the field path (``plan.json: drill.diameter_mm must be ...``).
    """
    return merge_parts([read_parts(path)])


def load_plan(path: str | os.PathLike[str]) -> Plan:
    """Read a plan file holding exactly one trajectory (see :func:`load_plans`)."""
    plans = load_plans(path)
    if len(plans) != 1:
        raise PlanInputError(
            f"{Path(path).name}: holds {len(plans)} trajectories (Line markups); "
            "keep one or load them with load_plans()"
        )
    return plans[0]


def load_plan_set(paths: Sequence[str | os.PathLike[str]]) -> tuple[Plan, ...]:
    """Read several plan files (or folders of them, :func:`plan_inputs`) and merge them into
    plans.

    Every file's landmarks protect every trajectory; a trajectory or landmark given by two
    files must agree (see :mod:`ctdrill.imaging.plan.merge`).
    """
    files = plan_inputs(paths)
    if not files:
        raise PlanInputError("no plan file given; name a plan file or a folder of them")
    parts: list[PlanParts] = []
    names: set[str] = set()
    for f in files:
        parts.append(read_input(f))
        names.update(p.name for p in parts[-1].trajectories)
        if len(names) > MAX_TRAJECTORIES:
            raise PlanInputError(
                f"{f.name}: the plan files hold more than the {MAX_TRAJECTORIES} trajectories a "
                "plan may hold (counted up to this file); split the case into several plans"
            )
    return merge_parts(parts)


def load_one_plan(paths: Sequence[str | os.PathLike[str]], trajectory: str | None = None) -> Plan:
    """:func:`load_plan_set` for commands that drill one trajectory (rehearse).

    ``trajectory`` picks one of several by its name, or by its number (1-based, in the order
    :func:`load_plan_set` gives them); None requires the files to hold exactly one.
    """
    return pick_plan(load_plan_set(paths), trajectory)


def pick_plan(plans: Sequence[Plan], trajectory: str | None = None) -> Plan:
    """The trajectory of ``plans`` that ``trajectory`` names (:func:`load_one_plan`)."""
    names = ", ".join(f"{i + 1}: {p.name!r}" for i, p in enumerate(plans))
    if trajectory is not None:
        for p in plans:
            if p.name == trajectory:
                return p
        number = ascii_whole(trajectory)
        if number is not None and 1 <= number <= len(plans):
            return plans[number - 1]
        raise PlanInputError(
            f"--trajectory {trajectory!r}: the plan files hold no trajectory of that name or "
            f"number; they hold {names}"
        )
    if len(plans) != 1:
        raise PlanInputError(
            f"the plan files hold {len(plans)} trajectories ({names}); pick one with "
            "--trajectory NAME (or its number)"
        )
    return plans[0]
