"""The zoomed views of one implant on its clinical page: the cross-section through its axis and
the panoramic reformat around it, each with the distances drawn and labelled.

Drawn by :func:`ctdrill.app.reformat.draw.draw_reformat` (the same code as the window's and
``ctdrill panorama``): the implant red when its plan has a problem. On top: a line from the
implant's apex to the nearest point of each canal's surface, labelled with the implant-to-canal
distance (red inside the margin), and the thinnest buccal and lingual walls written beside the
implant. The views are zoomed to :data:`ZOOM_MM` around the implant.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from ctdrill.app.report.entries import Entry
from ctdrill.app.report.layout import MARGIN_IN, PAGE_IN
from ctdrill.engine.case import PreparedCase
from ctdrill.engine.implant_facts import ImplantFacts
from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.plan.implants import implant_placement
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.resolution import format_clearance_mm
from ctdrill.imaging.sampling.reformat_types import Reformat

#: Half the side of the zoomed window around the implant, mm.
ZOOM_MM = 14.0
#: Colours of a distance that keeps / breaks its margin.
OK_COLOUR, BAD_COLOUR = "#20a040", "#e02020"


def _nearest_canal_point(plan: Plan, apex: np.ndarray) -> tuple[np.ndarray, float] | None:
    """The point of the nearest canal's surface to ``apex`` and its radius (centreline point
    moved by the radius towards the apex), or None without a canal."""
    best: tuple[float, np.ndarray] | None = None
    for lm in plan.landmarks:
        pts = getattr(lm, "points_lps", None)
        if lm.kind != "canal" or pts is None or len(pts) < 2:
            continue
        a, b = pts[:-1], pts[1:]
        ab = b - a
        t = np.clip(((apex - a) * ab).sum(1) / np.maximum((ab * ab).sum(1), 1e-12), 0.0, 1.0)
        foot = a + t[:, None] * ab
        d = np.linalg.norm(foot - apex, axis=1)
        k = int(np.argmin(d))
        if best is None or d[k] < best[0]:
            towards = apex - foot[k]
            n = float(np.linalg.norm(towards))
            surface = foot[k] + (towards / n if n > 0 else 0.0) * float(lm.radius_mm)
            best = (float(d[k]), surface)
    return None if best is None else (best[1], best[0])


def _zoom(ax: Axes, ref: Reformat, centre_lps: np.ndarray) -> None:
    uv, _ = ref.project(centre_lps[None, :])
    u, v = float(uv[0, 0]), float(uv[0, 1])
    if np.isfinite(u) and np.isfinite(v):
        ax.set_xlim(u - ZOOM_MM, u + ZOOM_MM)
        ax.set_ylim(v + ZOOM_MM, v - ZOOM_MM)


def annotate(ax: Axes, ref: Reformat, plan: Plan, facts: ImplantFacts) -> None:
    """The implant-to-canal line and label, and the walls' label (module docstring)."""
    place = implant_placement(plan)
    if place is None:
        return
    near = _nearest_canal_point(plan, place.apex_lps)
    if near is not None and facts.nerve_mm is not None:
        surface, _ = near
        uv, _ = ref.project(np.stack([place.apex_lps, surface]))
        if np.isfinite(uv).all():
            bad = facts.nerve_margin_mm is not None and facts.nerve_mm < facts.nerve_margin_mm
            colour = BAD_COLOUR if bad else OK_COLOUR
            ax.plot(uv[:, 0], uv[:, 1], color=colour, lw=1.6)
            text = f"{format_clearance_mm(facts.nerve_mm, facts.accuracy_mm)} mm to canal"
            ax.annotate(
                text,
                xy=(float(uv[1, 0]), float(uv[1, 1])),
                xytext=(8, 10),
                textcoords="offset points",
                color=colour,
                fontsize=8,
                fontweight="bold",
                bbox={"fc": "black", "ec": colour, "alpha": 0.7, "pad": 2},
            )
    walls = [
        f"{name} {format_clearance_mm(v, facts.accuracy_mm)} mm"
        for name, v in (("buccal", facts.buccal_mm), ("lingual", facts.lingual_mm))
        if v is not None
    ]
    if not walls and facts.min_wall_mm is not None:
        walls = [f"thinnest wall {format_clearance_mm(facts.min_wall_mm, facts.accuracy_mm)} mm"]
    if walls:
        uv, _ = ref.project(place.platform_lps[None, :])
        if np.isfinite(uv).all():
            thin = facts.min_wall_mm is not None and facts.min_wall_mm < plan.min_wall_mm
            ax.annotate(
                "walls: " + ", ".join(walls),
                xy=(float(uv[0, 0]), float(uv[0, 1])),
                xytext=(12, -14),
                textcoords="offset points",
                color=BAD_COLOUR if thin else OK_COLOUR,
                fontsize=8,
                fontweight="bold",
                bbox={"fc": "black", "ec": "none", "alpha": 0.7, "pad": 2},
            )


def implant_views(
    fig: Figure,
    top_in: float,
    height_in: float,
    case: PreparedCase,
    entry: Entry,
    facts: ImplantFacts,
    others: Sequence[Entry],
    pano: Reformat | None,
) -> str | None:
    """Draw the zoomed cross-section and panoramic of ``entry``'s implant side by side in the
    band ``top_in``..``top_in + height_in`` of ``fig`` (``pano``: the case's panoramic
    reformat, computed once); returns why they are not drawn (no arch, a reformat refused),
    or None."""
    from ctdrill.app.reformat.draw import draw_reformat
    from ctdrill.imaging.sampling.reformat import cross_section

    plan = entry.result.plan
    arch = case.plans[0].arch_lps if case.plans else None
    if arch is None:
        return "no dental arch in the plan: no cross-section or panoramic (docs/plan.md)"
    arch = np.asarray(arch)
    place = implant_placement(plan)
    centre = (
        plan.planned_target_lps if place is None else 0.5 * (place.apex_lps + place.platform_lps)
    )
    offending = [bool(e.result.warnings and _problem(e)) for e in others]
    plans = [e.result.plan for e in others]
    paths = [e.result for e in others]
    width = (PAGE_IN[0] - MARGIN_IN[0] - MARGIN_IN[1]) / 2.0 - 0.3
    bottom = PAGE_IN[1] - top_in - height_in + 0.45
    h = max(1.0, height_in - 0.75)
    try:
        for k, kind in enumerate(("cross-section", "panoramic")):
            left = MARGIN_IN[0] + 0.35 + k * (width + 0.3)
            ax = fig.add_axes(
                (left / PAGE_IN[0], bottom / PAGE_IN[1], width / PAGE_IN[0], h / PAGE_IN[1])
            )
            if kind == "cross-section":
                ref = cross_section(case.volume, arch, axis=(plan.entry_lps, plan.target_lps))
            elif pano is None:
                ax.set_axis_off()
                continue
            else:
                ref = pano
            draw_reformat(
                ax, ref, plans, paths=paths, offending=offending, title=f"{kind} (zoomed)"
            )
            _zoom(ax, ref, centre)
            annotate(ax, ref, plan, facts)
    except ImagingInputError as exc:
        return f"not drawn: {exc}"
    return None


def _problem(entry: Entry) -> bool:
    from ctdrill.warning_codes import banner_codes

    codes = set(banner_codes())
    return any(w.code in codes for w in entry.result.warnings)


def case_panorama(case: PreparedCase, entries: Sequence[Entry]) -> Reformat | None:
    """The case's panoramic reformat around every implant (None without an arch or when the
    arch is refused)."""
    from ctdrill.app.reformat.region import arch_region
    from ctdrill.imaging.sampling.reformat import panorama

    arch = case.plans[0].arch_lps if case.plans else None
    if arch is None:
        return None
    plans = [e.result.plan for e in entries]
    try:
        height, centre = arch_region(case.volume, np.asarray(arch), plans)
        return panorama(case.volume, np.asarray(arch), height_mm=height, centre_z_mm=centre)
    except ImagingInputError:
        return None
