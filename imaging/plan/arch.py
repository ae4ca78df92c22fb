"""The dental arch: a polyline in LPS mm that panoramic and cross-sectional views follow.

A plan's arch (plan key ``arch_mm``, :attr:`ctdrill.imaging.plan.types.Plan.arch_lps`) is the
curve a planner draws along the jaw, usually on an axial slice through the bone: the
panoramic reformat is the surface swept by it vertically, cross-sections are perpendicular to
it. It is shared by every trajectory of a plan file, as the landmarks are.

Rules (:func:`arch_error`): at least 2 points, at most :data:`MAX_ARCH_POINTS`, every
coordinate finite and within the plan's coordinate limit, consecutive points distinct (a
repeated point has no direction, so no perpendicular).

In 3D Slicer the arch is a **Curve** markup whose name or first control point's description
says ``arch`` (the word, any case); see :mod:`ctdrill.imaging.plan.slicer`.
"""

from __future__ import annotations

import re

import numpy as np

#: Most points an arch may hold (a hand-drawn arch has tens; a Slicer spline of 2000
#: control points, sampled 10 per segment, stays below it).
MAX_ARCH_POINTS = 20_001
#: Consecutive arch points closer than this (mm) are refused as repeated.
MIN_ARCH_STEP_MM = 1e-6
#: The word that makes a Slicer Curve the arch.
ARCH_WORD = re.compile(r"\barch\b", re.IGNORECASE)


def arch_error(points: object, max_coord_mm: float) -> str | None:
    """Why ``points`` is not an arch, or None when it is one.

    The message starts with the offending index where there is one (``[3] ...``) so callers
    prefix the field (``arch_mm[3] ...``).
    """
    try:
        arr = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        return " must be a list of [x, y, z] points in mm"
    if arr.ndim != 2 or arr.shape[1] != 3:
        return " must be a list of [x, y, z] points in mm"
    if len(arr) < 2:
        return f" must hold at least 2 points, got {len(arr)}"
    if len(arr) > MAX_ARCH_POINTS:
        return f" holds {len(arr)} points, more than the {MAX_ARCH_POINTS} accepted"
    bad = np.flatnonzero(~np.all(np.isfinite(arr) & (np.abs(arr) <= max_coord_mm), axis=1))
    if bad.size:
        i = int(bad[0])
        return (
            f"[{i}] must be 3 finite numbers [x, y, z] in mm (|v| <= {max_coord_mm:g}), "
            f"got {arr[i].tolist()}"
        )
    steps = np.linalg.norm(np.diff(arr, axis=0), axis=1)
    rep = np.flatnonzero(~(steps >= MIN_ARCH_STEP_MM))
    if rep.size:
        i = int(rep[0]) + 1
        return f"[{i}] repeats the point before it ({arr[i].tolist()}); remove it"
    return None


def is_arch_label(*texts: object) -> bool:
    """True when any of ``texts`` (a markup's name, a control point's description) says
    ``arch`` as a word, in any case."""
    return any(isinstance(t, str) and ARCH_WORD.search(t) is not None for t in texts)
