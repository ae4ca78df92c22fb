"""The dental arch: a polyline in LPS mm that panoramic and cross-sectional views follow.

A plan's arch (plan key ``arch_mm``, :attr:`ctdrill.imaging.plan.types.Plan.arch_lps`) is the
curve a planner draws along the jaw, usually on an axial slice through the bone: the
panoramic reformat is the surface swept by it vertically, cross-sections are perpendicular to
it. It is shared by every trajectory of a plan file, as the landmarks are.

Rules (:func:`arch_error`): at least 2 points, at most :data:`MAX_ARCH_POINTS`, every
coordinate finite and within the plan's coordinate limit, consecutive points distinct (a
repeated point has no direction, so no perpendicular).

In 3D Slicer the arch is a **Curve** markup marked by an explicit setting, never by a word
somewhere in its name (:func:`is_arch_curve`; a canal named "IAN canal below the arch" stays a
canal); see :mod:`ctdrill.imaging.plan.slicer`.
"""

from __future__ import annotations

import numpy as np

from ctdrill.imaging.plan.settings import free_text

#: Most points an arch may hold (a hand-drawn arch has tens; a Slicer spline of 2000
#: control points, sampled 10 per segment, stays below it).
MAX_ARCH_POINTS = 20_001
#: Consecutive arch points closer than this (mm) are refused as repeated.
MIN_ARCH_STEP_MM = 1e-6
#: The description that makes a Slicer Curve the arch: its free text (the words that are not
#: ``key=value`` settings) is exactly this word, any case.
ARCH_ROLE = "arch"
#: The name the markups writer gives the arch Curve; a Curve whose description holds no
#: setting and no other word and whose name is exactly this (any case) is the arch too.
ARCH_MARKUP_NAME = "dental arch"


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


def is_arch_curve(description: object, name: object) -> bool:
    """True when a Slicer Curve is the dental arch, from explicit settings only.

    Parameters
    ----------
    description : its first placed control point's description (Slicer keeps it).
    name : its markup name (Slicer's node name).

    The arch is the Curve whose description's free text is exactly :data:`ARCH_ROLE`
    (``arch``, any case; settings such as ``curve=polyline`` may follow), or whose name is
    exactly :data:`ARCH_MARKUP_NAME` while its description is empty. A word inside a name or
    a ``name=`` setting never makes a Curve the arch, so a canal is never taken for it.
    """
    text = description if isinstance(description, str) else ""
    words = free_text(text).split()
    if [w.lower() for w in words] == [ARCH_ROLE]:
        return True
    if text.strip():
        return False
    return isinstance(name, str) and " ".join(name.split()).lower() == ARCH_MARKUP_NAME
