"""One plan from several files: 3D Slicer saves one markup per file.

The inputs (``--plan`` repeated, or a folder) are read in order (a folder's ``*.json`` /
``*.mrk.json`` plan files and ``*.seg.nrrd`` segmentations, sorted by name) and merged:

- every trajectory (a ``ctdrill-plan/1`` file, a Line markup) becomes one plan;
- every landmark of every file protects every trajectory;
- a trajectory, or a landmark of one kind (canal, point, mask), named the same in two files
  must be the same there (it is then kept once); if the two disagree the merge is refused
  naming both files (a Curve and a segment may share a name: both are kept);
- the dental arch (``arch_mm``, an arch Curve) is shared by every trajectory too; two files
  giving different arches are refused naming both;
- at least one trajectory is required, at most
  :data:`~ctdrill.imaging.plan.types.MAX_TRAJECTORIES` in all (counted as the files are read:
  a folder of thousands of plans is refused at the first file past the limit).
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import TypeVar

import numpy as np

from ctdrill.imaging.plan.landmarks import Landmark
from ctdrill.imaging.plan.read import PlanParts, read_parts
from ctdrill.imaging.plan.types import MAX_TRAJECTORIES, Plan, PlanInputError

#: Segmentation files a folder contributes (plain ``.nrrd`` is not taken from a folder: Slicer
#: saves volumes, the CT itself included, as ``.nrrd``).
FOLDER_SEGMENTATIONS = (".seg.nrrd",)
#: Label files accepted when named explicitly.
LABEL_SUFFIXES = (".seg.nrrd", ".nrrd", ".nhdr", ".nii.gz", ".nii", ".mha", ".mhd", ".dcm")

_T = TypeVar("_T")


def _lower(path: Path) -> str:
    return path.name.lower()


def plan_inputs(paths: Sequence[str | os.PathLike[str]]) -> list[Path]:
    """The files named by ``paths``: files as given, folders expanded (see module doc)."""
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
        from ctdrill.imaging.plan.segmentation import segmentation_parts

        return segmentation_parts(path)
    return read_parts(path)


def load_merged(paths: Sequence[str | os.PathLike[str]]) -> tuple[Plan, ...]:
    """Read and merge every input of ``paths`` (see module doc)."""
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


def merge_parts(parts: Sequence[PlanParts]) -> tuple[Plan, ...]:
    """Merge the parts of several files into plans (see module doc)."""
    trajectories: dict[str, tuple[Plan, Path]] = {}
    landmarks: dict[tuple[str, str], tuple[Landmark, Path]] = {}
    arch: tuple[np.ndarray, Path] | None = None
    for part in parts:
        if part.arch is not None:
            if arch is None:
                arch = (part.arch, part.source)
            elif not np.array_equal(arch[0], part.arch):
                raise PlanInputError(
                    f"{part.source.name}: its dental arch disagrees with the one in "
                    f"{arch[1].name}; a plan has one arch: remove one of them"
                )
        for plan in part.trajectories:
            seen = trajectories.get(plan.name)
            if seen is None:
                trajectories[plan.name] = (plan, part.source)
            elif not _same_trajectory(seen[0], plan):
                raise PlanInputError(
                    f"{part.source.name}: trajectory {plan.name!r} disagrees with the one in "
                    f"{seen[1].name} (entry, target or settings differ); remove one of the "
                    "files or rename one trajectory"
                )
        for lm in part.landmarks:
            seen_lm = landmarks.get((lm.kind, lm.name))
            if seen_lm is None:
                landmarks[(lm.kind, lm.name)] = (lm, part.source)
            elif not _same_landmark(seen_lm[0], lm):
                raise PlanInputError(
                    f"{part.source.name}: landmark {lm.name!r} disagrees with the one in "
                    f"{seen_lm[1].name}; remove one of the files or rename one landmark"
                )
    if not trajectories:
        names = ", ".join(p.source.name for p in parts)
        raise PlanInputError(
            f"{names}: no trajectory (a Line markup or a ctdrill-plan/1 file); add the file "
            "holding the drill's Line"
        )
    notes = _unique(n for p in parts for n in p.notes)
    warnings = _unique(w for p in parts for w in p.warnings)
    all_landmarks = tuple(lm for lm, _ in landmarks.values())
    return tuple(
        replace(
            plan,
            landmarks=all_landmarks,
            notes=notes,
            warnings=warnings,
            arch_lps=None if arch is None else arch[0],
        )
        for plan, _ in trajectories.values()
    )


def _unique(items: Iterable[_T]) -> tuple[_T, ...]:
    return tuple(dict.fromkeys(items))


def _same_trajectory(a: Plan, b: Plan) -> bool:
    return (
        np.array_equal(a.entry_lps, b.entry_lps)
        and np.array_equal(a.target_lps, b.target_lps)
        and (a.drills, a.feed_mm_s, a.calibration, a.margin_mm, a.implant, a.min_wall_mm, a.site)
        == (b.drills, b.feed_mm_s, b.calibration, b.margin_mm, b.implant, b.min_wall_mm, b.site)
    )


def _same_landmark(a: Landmark, b: Landmark) -> bool:
    return a.margin_mm == b.margin_mm and a.same_shape(b)
