"""Draw a reformat (panorama or cross-section) with the plan on a matplotlib axes.

One drawing for ``ctdrill panorama``, the GUI's panorama and cross-section views and the report:
the CT image at its true millimetre extent (equal aspect), each canal's tube outline and its
margin zone (shaded) where they reach the slab, the implant body, the drill (its diameter, down
to the stop depth when a path result is given; the planned axis otherwise), the arch position
(a marker on a cross-section; the cross-section's position on a panorama), a millimetre scale
bar and orientation letters. Whatever lies outside the slab is named in a caption instead of
being hidden. Geometry comes from :mod:`ctdrill.app.reformat.overlay`; fonts are 10 pt or more.
"""

from __future__ import annotations

import textwrap
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib import patheffects

from ctdrill.app.reformat.overlay import (
    BodyOverlay,
    TubeOverlay,
    body_overlay,
    drill_profile_mm,
    tube_overlay,
)
from ctdrill.app.reformat.placement import implant_body
from ctdrill.imaging.display import WINDOW_PRESETS
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.sampling.reformat import Reformat

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from ctdrill.engine.path import PathResult

#: Default window: the implant-planning preset (the slice views offer it too).
DEFAULT_LEVEL_HU, DEFAULT_WIDTH_HU = WINDOW_PRESETS["implant planning"]
#: Smallest font, pt.
FONT_PT = 10.0
CANAL_COLOUR = "#ffd400"
MARGIN_COLOUR = "#ff8c00"
IMPLANT_COLOUR = "#4fc3f7"
#: An implant with a plan problem (a margin, a wall, a perforation, too close, above the entry).
OFFENDING_COLOUR = "#ff3030"
DRILL_COLOUR = "#ff4fd8"
ARCH_COLOUR = "#7cfc00"
_STROKE = [patheffects.withStroke(linewidth=2.5, foreground="black")]
#: Caption lines are wrapped at this many characters.
_CAPTION_CHARS = 90
#: Scale bar lengths tried, mm (the longest at most a quarter of the image width).
_BAR_MM = (1.0, 2.0, 5.0, 10.0, 20.0, 50.0)


@dataclass
class ReformatDrawing:
    """What :func:`draw_reformat` drew and said.

    Attributes
    ----------
    tubes : list[TubeOverlay]
        Canals (and point landmarks) considered, drawn where ``visible``.
    bodies : list[BodyOverlay]
        Implants and drills considered, drawn where ``visible``.
    captions : list[str]
        Lines written on the image (what is not drawn, and why; the slab).
    scale_bar_mm : float
        Length of the scale bar, mm.
    """

    tubes: list[TubeOverlay] = field(default_factory=list)
    bodies: list[BodyOverlay] = field(default_factory=list)
    captions: list[str] = field(default_factory=list)
    scale_bar_mm: float = 0.0


def draw_reformat(
    ax: Axes,
    reformat: Reformat,
    plans: Sequence[Plan],
    *,
    paths: Sequence[PathResult | None] | None = None,
    level_hu: float = DEFAULT_LEVEL_HU,
    width_hu: float = DEFAULT_WIDTH_HU,
    cross_section_at_mm: float | None = None,
    title: str | None = None,
    captions: Sequence[str] = (),
    offending: Sequence[bool] = (),
) -> ReformatDrawing:
    """Draw ``reformat`` and the plans on ``ax`` (module docstring).

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Target axes (cleared first).
    reformat : Reformat
        The panorama or cross-section.
    plans : Sequence[Plan]
        Trajectories (implants) to draw; landmarks shared between them are drawn once.
    paths : Sequence[PathResult | None] | None
        Path results aligned with ``plans``: the drill is drawn to each one's stop depth.
    level_hu, width_hu : float
        Display window (default: the implant-planning preset).
    cross_section_at_mm : float | None
        On a panorama, the arc position of a cross-section to mark.
    title : str | None
        Axes title.
    captions : Sequence[str]
        More lines to write under the image (e.g. why a drill's stop is not known).
    offending : Sequence[bool]
        Aligned with ``plans``: the implants with a plan problem, drawn red.

    Returns
    -------
    ReformatDrawing
    """
    out = ReformatDrawing()
    ax.clear()
    p = reformat.pixel_mm
    h, w = reformat.shape
    lo, hi = level_hu - 0.5 * width_hu, level_hu + 0.5 * width_hu
    ax.imshow(
        reformat.hu,
        cmap="gray",
        vmin=lo,
        vmax=hi,
        extent=(-0.5 * p, (w - 0.5) * p, (h - 0.5) * p, -0.5 * p),
        interpolation="bilinear",
        origin="upper",
    )
    ax.set_aspect("equal")
    ax.set_xlim(-0.5 * p, (w - 0.5) * p)
    ax.set_ylim((h - 0.5) * p, -0.5 * p)
    ax.set_xlabel("along the arch (mm)" if reformat.kind == "panorama" else "across (mm)")
    ax.set_ylabel("mm")
    ax.tick_params(labelsize=FONT_PT)
    ax.xaxis.label.set_fontsize(FONT_PT + 1)
    ax.yaxis.label.set_fontsize(FONT_PT + 1)
    if title:
        ax.set_title(title, fontsize=FONT_PT + 2)
    _draw_landmarks(ax, reformat, plans, out)
    _draw_bodies(ax, reformat, plans, paths, out, offending)
    _draw_arch_marks(ax, reformat, cross_section_at_mm)
    out.scale_bar_mm = _scale_bar(ax, reformat)
    _letters(ax, reformat)
    slab = (
        f"slab {reformat.slab_mm:g} mm {reformat.slab_mode}"
        if reformat.slab_mm > 0
        else "no slab (one plane)"
    )
    out.captions.extend([*reformat.notes, *captions])
    _captions(ax, [*out.captions, f"{slab}, pixel {p:.2f} mm, W/L {width_hu:g}/{level_hu:g}"])
    return out


def _margin_of(landmark: Any, plan: Plan) -> float:
    own = landmark.margin_mm
    return float(plan.margin_mm if own is None else own)


def _draw_landmarks(
    ax: Axes, reformat: Reformat, plans: Sequence[Plan], out: ReformatDrawing
) -> None:
    seen: list[Any] = []
    for plan in plans:
        for landmark in plan.landmarks:
            if any(landmark.same_shape(other) for other in seen):
                continue
            seen.append(landmark)
            drawing = landmark.drawing()
            margin = _margin_of(landmark, plan)
            items = [*drawing.polylines_lps, *(pt[None] for pt in drawing.points_lps)]
            for k, line in enumerate(items):
                name = landmark.name if len(items) == 1 else f"{landmark.name} [{k + 1}]"
                tube = tube_overlay(reformat, line, drawing.radius_mm, margin, name)
                out.tubes.append(tube)
                caption = tube.caption()
                if caption:
                    out.captions.append(caption)
                else:
                    _draw_tube(ax, reformat, tube)
            if len(drawing.surface_lps):
                _draw_cloud(ax, reformat, drawing.surface_lps, margin)


def _draw_tube(ax: Axes, reformat: Reformat, tube: TubeOverlay) -> None:
    p = reformat.pixel_mm
    h, w = reformat.shape
    xs, ys = np.arange(w) * p, np.arange(h) * p
    d = np.where(np.isfinite(tube.distance_mm), tube.distance_mm, 1e9)
    outer = tube.radius_mm + tube.margin_mm
    if tube.margin_mm > 0 and np.any(d <= outer):
        ax.contourf(xs, ys, d, levels=[tube.radius_mm, outer], colors=[MARGIN_COLOUR], alpha=0.35)
        ax.contour(xs, ys, d, levels=[outer], colors=[MARGIN_COLOUR], linewidths=0.8)
    if tube.radius_mm > 0 and np.any(d <= tube.radius_mm):
        ax.contour(xs, ys, d, levels=[tube.radius_mm], colors=[CANAL_COLOUR], linewidths=1.6)
    for run in tube.centre_runs_uv:
        ax.plot(run[:, 0], run[:, 1], color=CANAL_COLOUR, lw=0.9, ls="--")


def _draw_cloud(ax: Axes, reformat: Reformat, surface_lps: np.ndarray, margin_mm: float) -> None:
    uv, off = reformat.project(surface_lps)
    near = np.all(np.isfinite(uv), axis=1) & (np.abs(off) <= 0.5 * reformat.slab_mm + margin_mm)
    if near.any():
        ax.plot(uv[near, 0], uv[near, 1], ".", color=CANAL_COLOUR, ms=2)


def _draw_bodies(
    ax: Axes,
    reformat: Reformat,
    plans: Sequence[Plan],
    paths: Sequence[PathResult | None] | None,
    out: ReformatDrawing,
    offending: Sequence[bool] = (),
) -> None:
    for k, plan in enumerate(plans):
        label = plan.name if len(plans) > 1 else "implant"
        implant = implant_body(plan)
        if implant is not None:
            base, axis, s, r, spec_name = implant
            body = body_overlay(reformat, base, axis, s, r, f"{label} ({spec_name})")
            red = k < len(offending) and offending[k]
            _show_body(ax, body, OFFENDING_COLOUR if red else IMPLANT_COLOUR, fill=False, out=out)
        entry, target = plan.entry_lps, plan.target_lps
        axis = target - entry
        path = None if paths is None or k >= len(paths) else paths[k]
        if path is None:
            uv, _ = reformat.project(np.stack([entry, target]))
            if np.all(np.isfinite(uv)):
                ax.plot(uv[:, 0], uv[:, 1], color="white", lw=1.0, ls=":")
            continue
        drill = path.plan.drill
        s, r = drill_profile_mm(path.stop_depth_mm, drill.diameter_mm, drill.tip_length_mm)
        name = f"drill {drill.diameter_mm:g} mm to {path.stop_depth_mm:.1f} mm"
        body = body_overlay(reformat, entry, axis, s, r, f"{label}: {name}")
        _show_body(ax, body, DRILL_COLOUR, fill=True, out=out)


def _show_body(
    ax: Axes, body: BodyOverlay, colour: str, *, fill: bool, out: ReformatDrawing
) -> None:
    out.bodies.append(body)
    caption = body.caption()
    if caption:
        out.captions.append(caption)
        return
    xy = body.outline_uv
    if fill:
        ax.fill(xy[:, 0], xy[:, 1], color=colour, alpha=0.35, lw=0)
    ax.plot(xy[:, 0], xy[:, 1], color=colour, lw=1.6)
    ax.plot(body.axis_uv[:, 0], body.axis_uv[:, 1], color=colour, lw=0.8, ls="--")


def _draw_arch_marks(ax: Axes, reformat: Reformat, cross_section_at_mm: float | None) -> None:
    if reformat.kind == "panorama" and cross_section_at_mm is not None:
        ax.axvline(cross_section_at_mm, color=ARCH_COLOUR, lw=1.0, ls="--")
        return
    point = reformat.arch_point_lps()
    if point is None:
        return
    uv, _ = reformat.project(point[None])
    u, v = float(uv[0, 0]), float(uv[0, 1])
    ax.plot([u], [v], marker="v", color=ARCH_COLOUR, ms=10, mec="black")
    ax.text(
        u + 1.0,
        v,
        "arch",
        color=ARCH_COLOUR,
        fontsize=FONT_PT,
        ha="left",
        va="center",
        path_effects=_STROKE,
    )


def _scale_bar(ax: Axes, reformat: Reformat) -> float:
    width_mm, height_mm = reformat.extent_mm
    bar = max([b for b in _BAR_MM if b <= 0.25 * width_mm] or [_BAR_MM[0]])
    x0 = 0.04 * width_mm
    y0 = 0.95 * height_mm
    ax.plot(
        [x0, x0 + bar], [y0, y0], color="white", lw=3, solid_capstyle="butt", path_effects=_STROKE
    )
    ax.text(
        x0 + 0.5 * bar,
        y0 - 0.015 * height_mm,
        f"{bar:g} mm",
        color="white",
        fontsize=FONT_PT + 1,
        ha="center",
        va="bottom",
        path_effects=_STROKE,
    )
    return bar


def _letters(ax: Axes, reformat: Reformat) -> None:
    left, right = reformat.column_letters
    style: dict[str, Any] = {
        "color": "white",
        "fontsize": FONT_PT + 3,
        "fontweight": "bold",
        "transform": ax.transAxes,
        "path_effects": _STROKE,
    }
    ax.text(0.012, 0.5, left, ha="left", va="center", **style)
    ax.text(0.988, 0.5, right, ha="right", va="center", **style)
    ax.text(0.5, 0.985, "S", ha="center", va="top", **style)
    ax.text(0.5, 0.015, "I", ha="center", va="bottom", **style)


def _captions(ax: Axes, lines: list[str]) -> None:
    """Captions go under the x-axis label, outside the image (layouts make room for them),
    wrapped to ``_CAPTION_CHARS`` characters."""
    label = ax.get_xlabel()
    wrapped = [part for line in lines for part in textwrap.wrap(line, _CAPTION_CHARS)]
    ax.set_xlabel("\n".join([label, *wrapped]), fontsize=FONT_PT + 1, linespacing=1.4)
