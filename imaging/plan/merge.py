"""One plan from several files: 3D Slicer saves one markup per file.

The inputs (``--plan`` repeated, or a folder) are read in order (a folder's ``*.json`` /
``*.mrk.json`` plan files and ``*.seg.nrrd`` segmentations, sorted by name:
:func:`ctdrill.imaging.plan.load.load_plan_set`) and their parts merged here:

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

from collections.abc import Iterable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import TypeVar

import numpy as np

from ctdrill.imaging.plan.landmarks import Landmark
from ctdrill.imaging.plan.read import PlanParts
from ctdrill.imaging.plan.types import Plan, PlanInputError

_T = TypeVar("_T")


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
