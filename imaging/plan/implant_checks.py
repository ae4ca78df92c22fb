"""What a planned implant and the drill's stop, or two implants, say about each other.

Warnings (codes documented in ``docs/export.md``):

- ``implant_beyond_stop``: the drill's full diameter stops (margin, end of the volume)
  shallower than the implant's apex, which sits at the planned target: the osteotomy is
  shorter than the implant, which cannot be seated where planned. A drill drilled for the
  implant (``Plan.drilled(k)``) is planned to the apex plus its tip length; its full diameter
  reaches its stop less that tip length (``overdrill_mm``). The stop wins: it is what the
  device enforces.
- ``implant_above_entry``: the implant is longer than the planned depth, so its platform
  stands above the entry point (outside the bone where the entry is on the crest).
- ``implants_too_close``: two implants of one plan set closer than
  :data:`~ctdrill.imaging.plan.implants.MIN_IMPLANT_DISTANCE_MM` (3 mm, DESIGN.md section 5).
  The gap is measured between each body's **platform capsule**: the points within the
  platform radius of its axis segment (platform to apex). That capsule holds the whole body
  (the platform is the widest part), so the gap measured is never larger than the true one;
  for two parallel implants level with each other it is exactly the gap between their
  platforms, where clinicians measure it.

The drill's final diameter is normally smaller than the implant's (the implant threads into
a narrower osteotomy), so no warning compares them.
"""

from __future__ import annotations

import numpy as np

from ctdrill.imaging.plan.implants import (
    MIN_IMPLANT_DISTANCE_MM,
    ImplantPlacement,
    implant_placement,
)
from ctdrill.imaging.plan.types import Plan
from ctdrill.warning_codes import LoadWarning

#: Depths closer than this (mm) are equal (a stop at the planned depth is at the apex).
DEPTH_TOL_MM = 1e-9


def implant_seated(
    place: ImplantPlacement, stop_depth_mm: float, tip_beyond_mm: float = 0.0
) -> bool:
    """Whether a drill stopping at ``stop_depth_mm`` reaches the implant's apex (its seat)
    with its full diameter, the part ``tip_beyond_mm`` above its tip (the plan's
    ``overdrill_mm``: the tip a drill for the implant is drilled beyond the apex)."""
    return stop_depth_mm - tip_beyond_mm >= place.apex_depth_mm - DEPTH_TOL_MM


def implant_warnings(plan: Plan, stop_depth_mm: float, stop_reason: str) -> tuple[LoadWarning, ...]:
    """``implant_beyond_stop`` and ``implant_above_entry`` for ``plan`` (see module doc)."""
    place = implant_placement(plan)
    if place is None:
        return ()
    spec = place.spec
    out: list[LoadWarning] = []
    if not implant_seated(place, stop_depth_mm, plan.overdrill_mm):
        tip = plan.overdrill_mm
        reach = (
            ""
            if tip == 0.0
            else f" (its full diameter to {stop_depth_mm - tip:.2f} mm, {tip:g} mm above its tip)"
        )
        out.append(
            LoadWarning(
                "implant_beyond_stop",
                f"plan {plan.name!r}: implant {spec.name!r} needs an osteotomy "
                f"{place.apex_depth_mm:.2f} mm deep (its apex at the target) but the drill "
                f"stops at {stop_depth_mm:.2f} mm ({stop_reason}){reach}: the implant cannot be "
                "seated where planned; plan it shallower or choose a shorter implant",
            )
        )
    if place.platform_depth_mm < -DEPTH_TOL_MM:
        out.append(
            LoadWarning(
                "implant_above_entry",
                f"plan {plan.name!r}: implant {spec.name!r} ({spec.length_mm:g} mm) is longer "
                f"than the planned depth ({place.apex_depth_mm:.2f} mm): its platform stands "
                f"{-place.platform_depth_mm:.2f} mm above the entry point; deepen the target "
                "or choose a shorter implant",
            )
        )
    return tuple(out)


def segment_distance_mm(p0: np.ndarray, p1: np.ndarray, q0: np.ndarray, q1: np.ndarray) -> float:
    """The distance between segments ``[p0, p1]`` and ``[q0, q1]`` (mm; closed form)."""
    d1, d2, r = p1 - p0, q1 - q0, p0 - q0
    a, e, f = float(d1 @ d1), float(d2 @ d2), float(d2 @ r)
    if a <= 0.0 and e <= 0.0:
        return float(np.linalg.norm(r))
    if a <= 0.0:
        s, t = 0.0, min(max(f / e, 0.0), 1.0)
    else:
        c = float(d1 @ r)
        if e <= 0.0:
            s, t = min(max(-c / a, 0.0), 1.0), 0.0
        else:
            b = float(d1 @ d2)
            denom = a * e - b * b
            s = min(max((b * f - c * e) / denom, 0.0), 1.0) if denom > 0.0 else 0.0
            t = (b * s + f) / e
            if t < 0.0:
                s, t = min(max(-c / a, 0.0), 1.0), 0.0
            elif t > 1.0:
                s, t = min(max((b - c) / a, 0.0), 1.0), 1.0
    return float(np.linalg.norm(p0 + s * d1 - (q0 + t * d2)))


def implant_gap_mm(a: Plan, b: Plan) -> float | None:
    """The gap between the implants of ``a`` and ``b`` (platform capsules, see module doc;
    negative when they overlap), or None when either has no implant."""
    pa, pb = implant_placement(a), implant_placement(b)
    if pa is None or pb is None:
        return None
    axis = segment_distance_mm(pa.platform_lps, pa.apex_lps, pb.platform_lps, pb.apex_lps)
    return axis - pa.spec.radius_mm - pb.spec.radius_mm


def implants_too_close(plans: tuple[Plan, ...]) -> dict[str, tuple[LoadWarning, ...]]:
    """``implants_too_close`` warnings of a plan set, by trajectory name (both of each pair)."""
    out: dict[str, list[LoadWarning]] = {}
    for i, a in enumerate(plans):
        for b in plans[i + 1 :]:
            gap = implant_gap_mm(a, b)
            if gap is None or not gap < MIN_IMPLANT_DISTANCE_MM:
                continue
            how = (
                f"intersect ({-gap:.2f} mm of overlap between their platform-wide bodies)"
                if gap < 0.0
                else f"are {gap:.2f} mm apart, less than the {MIN_IMPLANT_DISTANCE_MM:g} mm kept "
                "between implants (gap between their platform-wide bodies)"
            )
            message = f"implants of {a.name!r} and {b.name!r} {how}; move one of them"
            for name in (a.name, b.name):
                out.setdefault(name, []).append(LoadWarning("implants_too_close", message))
    return {k: tuple(v) for k, v in out.items()}
