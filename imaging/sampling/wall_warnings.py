"""The warnings of an implant's bone walls (:mod:`~ctdrill.imaging.sampling.walls`):
``thin_wall``, ``cortical_perforation`` and ``bone_walls_unknown``, with directions in a
surgeon's words."""

from __future__ import annotations

import numpy as np

from ctdrill.imaging.sampling.walls import PERFORATION_DEPTH_MM, BoneWalls
from ctdrill.warning_codes import LoadWarning


def bone_wall_warnings(walls: BoneWalls, *, min_wall_mm: float, label: str) -> list[LoadWarning]:
    """``thin_wall``, ``cortical_perforation`` and ``bone_walls_unknown`` for ``walls``
    (``label`` names the plan and implant in the messages)."""
    out: list[LoadWarning] = []
    if walls.min_mm is not None and walls.min_mm < min_wall_mm:
        assert walls.direction_lps is not None and walls.below_platform_mm is not None
        sides = ", ".join(
            f"{name} {value:.1f} mm"
            for name, value in (
                ("buccal", walls.buccal_mm),
                ("lingual", walls.lingual_mm),
            )
            if value is not None
        )
        out.append(
            LoadWarning(
                "thin_wall",
                f"{label}: the thinnest bone wall around the implant is {walls.min_mm:.1f} mm, "
                f"under {min_wall_mm:g} mm, {walls.below_platform_mm:.1f} mm below the platform "
                f"towards {_direction_text(walls.direction_lps, walls.buccal_lps)}"
                + (f" ({sides})" if sides else ""),
            )
        )
    p = walls.perforation
    if p is not None:
        out.append(
            LoadWarning(
                "cortical_perforation",
                f"{label}: the implant surface lies outside the jaw's bone from "
                f"{p.below_platform_mm[0]:.1f} to {p.below_platform_mm[1]:.1f} mm below the "
                f"platform, towards {_direction_text(p.direction_lps, walls.buccal_lps)} "
                f"({100 * p.fraction:.0f} % of "
                "the surface deeper than "
                f"{PERFORATION_DEPTH_MM:g} mm): the implant perforates the cortical plate",
            )
        )
    if walls.unknown_fraction > 0.0:
        out.append(
            LoadWarning(
                "bone_walls_unknown",
                f"{label}: {100 * walls.unknown_fraction:.0f} % of the directions around the "
                "implant leave the CT before bone ends; outside the CT counts as unknown, never "
                "as bone, so the walls there are not measured",
            )
        )
    return out


def _direction_text(direction: np.ndarray, buccal_lps: np.ndarray | None) -> str:
    """A direction in a surgeon's words where the arch is known (``buccal``, ``lingual``, or
    ``along the arch`` (mesial or distal), by the nearest within 45 deg), else in patient
    axes (:func:`_lps_text`)."""
    if buccal_lps is None:
        return _lps_text(direction)
    c = float(np.dot(direction, buccal_lps))
    if c >= np.cos(np.radians(45.0)):
        return "buccal"
    if c <= -np.cos(np.radians(45.0)):
        return "lingual"
    return "along the arch (mesial or distal)"


def _lps_text(direction: np.ndarray) -> str:
    """``"L 0.71 P 0.71"``-style patient direction of a unit vector (its main components)."""
    letters = (("R", "L"), ("A", "P"), ("I", "S"))
    parts = [
        f"{letters[i][int(direction[i] > 0)]} {abs(float(direction[i])):.2f}"
        for i in np.argsort(-np.abs(direction))
        if abs(float(direction[i])) >= 0.1
    ]
    return " ".join(parts)
