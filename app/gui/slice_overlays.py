"""Matplotlib drawing of an :class:`~ctdrill.app.gui.slice_scene.OverlayScene` on a slice:
where the plane cuts each solid (:mod:`ctdrill.app.gui.sections`), in in-plane mm.

- a canal: its tube (radius, filled) and the margin zone around it (shaded), with the
  centreline (solid where it runs within the tube's reach of the plane, dotted elsewhere);
- a drill: its diameter down to the stop (or the planned depth) with the cone tip, the planned
  axis dashed; the current trajectory bright, the others muted;
- an implant body: its outline (red with a plan problem, :mod:`ctdrill.app.gui.problems`);
- the arch (axial view): solid where it lies on the slice, dotted where it is projected.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import dataclass
from typing import Any

import numpy as np
from contourpy import FillType, LineType, contour_generator
from matplotlib.collections import PathCollection
from matplotlib.colors import to_rgb
from matplotlib.lines import Line2D
from matplotlib.patches import Polygon
from matplotlib.path import Path

from ctdrill.app.gui.scene import LandmarkGeometry
from ctdrill.app.gui.sections import Plane, TubeField, revolved_section, tube_field
from ctdrill.app.gui.slice_scene import BodyDrawing, OverlayScene, TrajectoryDrawing
from ctdrill.app.gui.slices import SliceImage, polyline_in_plane

#: Overlays within this distance of the plane are drawn solid, mm.
SLAB_MM = 2.0
#: Landmark colour, and the colour of a landmark whose margin the planned path breaks.
LANDMARK_COLOUR = "#ffd030"
VIOLATED_COLOUR = "#ff3030"
#: Drill colours: the trajectory being edited, the others.
CURRENT_COLOUR = "#4080ff"
OTHER_COLOUR = "#c090ff"
IMPLANT_COLOUR = "#40e080"
ARCH_COLOUR = "#ff9040"
STOP_COLOUR = "#ff40b0"
HANDLE_COLOURS = {"entry": "#40e0ff", "target": "#ff6060", "platform": "#40e080"}


#: Tube fields kept (the latest first): a plan edit that leaves a canal and a view's plane
#: as they were (a target moved, an undo, an implant picked) redraws it without recomputing.
#: Locked: :func:`cached_tube_field` may be called from any thread.
TUBE_CACHE_SIZE = 16
_tubes: OrderedDict[bytes, TubeField | None] = OrderedDict()
_tubes_lock = threading.Lock()


@dataclass(frozen=True, eq=False)
class TubeRequest:
    """The arguments of one canal's :func:`~ctdrill.app.gui.sections.tube_field` on a view's
    plane, and their cache key (by value)."""

    plane: Plane
    polyline_lps: np.ndarray
    reach_mm: float
    step_mm: float

    @property
    def key(self) -> bytes:
        pts = np.ascontiguousarray(self.polyline_lps, dtype=np.float64)
        plane = self.plane
        return b"".join(
            [
                np.asarray(a, dtype=np.float64).tobytes()
                for a in (plane.origin_lps, plane.u_lps, plane.v_lps, [self.reach_mm, self.step_mm])
            ]
            + [pts.tobytes()]
        )


def cached_tube_field(
    plane: Plane, polyline_lps: np.ndarray, reach_mm: float, step_mm: float
) -> TubeField | None:
    """:func:`~ctdrill.app.gui.sections.tube_field`, kept for the same arguments (by value)."""
    return _tube(TubeRequest(plane, np.asarray(polyline_lps), reach_mm, step_mm))


def _tube(request: TubeRequest) -> TubeField | None:
    """The kept field of ``request``, else computed and kept."""
    key = request.key
    with _tubes_lock:
        if key in _tubes:
            _tubes.move_to_end(key)
            return _tubes[key]
    pts = np.ascontiguousarray(request.polyline_lps, dtype=np.float64)
    field = tube_field(request.plane, pts, request.reach_mm, request.step_mm)
    with _tubes_lock:
        _tubes[key] = field
        while len(_tubes) > TUBE_CACHE_SIZE:
            _tubes.popitem(last=False)
    return field


def _tube_request(image: SliceImage, lm: LandmarkGeometry) -> TubeRequest | None:
    """The tube field ``_draw_canal`` draws ``lm`` with on ``image`` (None: none, a point or
    a cloud)."""
    if len(lm.points_lps) < 2 or lm.cloud:
        return None
    step = float(np.clip(min(image.pixel_mm, lm.radius_mm / 4.0), 0.05, 1.0))
    return TubeRequest(plane_of(image), lm.points_lps, lm.radius_mm + lm.margin_mm, step)


#: A ``plot`` format string's line style and marker (the few the views use).
_FORMATS: dict[str, tuple[Any, str]] = {
    "-": ("-", "None"),
    "--": ("--", "None"),
    ":": (":", "None"),
    "o": ("None", "o"),
    "s": ("None", "s"),
    "x": ("None", "x"),
}


def _line(ax: Any, x: Any, y: Any, fmt: str, **style: Any) -> Line2D:
    """``ax.plot(x, y, fmt, **style)``'s line, made and added directly (``plot`` parses its
    arguments, units and cycler for every call: ~0.2 ms of each of the 7-9 lines a view
    draws per pass)."""
    linestyle, marker = _FORMATS[fmt]
    line = Line2D(
        np.asarray(x, dtype=np.float64),
        np.asarray(y, dtype=np.float64),
        linestyle=linestyle,
        marker=marker,
        **style,
    )
    ax.add_line(line)
    return line


def plane_of(image: SliceImage) -> Plane:
    """The plane of a slice image."""
    return Plane(origin_lps=image.origin_lps, u_lps=image.u_lps, v_lps=image.v_lps)


def _draw_canal(ax: Any, image: SliceImage, lm: LandmarkGeometry) -> None:
    colour = VIOLATED_COLOUR if lm.violated else LANDMARK_COLOUR
    reach = lm.radius_mm + lm.margin_mm
    uv, near = polyline_in_plane(image, lm.points_lps, slab_mm=max(reach, SLAB_MM))
    if len(uv) == 1 or lm.cloud:
        _line(ax, uv[:, 0], uv[:, 1], "o", color=colour, ms=3 if lm.cloud else 5, zorder=3)
        return
    _line(ax, uv[:, 0], uv[:, 1], "-" if near.any() else ":", color=colour, lw=0.8, zorder=3)
    request = _tube_request(image, lm)
    field = None if request is None else _tube(request)
    if field is None or field.distance_mm.min() > reach:
        return
    # the tube filled, the margin zone shaded, their outlines: contourpy's polygons and lines
    # drawn as two path collections (matplotlib's ``contourf``/``contour`` built the same
    # geometry with ~10-20 ms of Python each, per view and per redraw)
    rgb = to_rgb(colour)
    bands: list[tuple[float, float, tuple[float, ...]]] = []
    lines: list[tuple[float, str, float]] = []  # (level, line style, width)
    if lm.radius_mm > 0.0:
        bands.append((-1.0, lm.radius_mm, (*rgb, 0.45)))
        lines.append((lm.radius_mm, "solid", 1.2))
    if lm.margin_mm > 0.0:
        bands.append((lm.radius_mm if bands else -1.0, reach, (*rgb, 0.15)))
        lines.append((reach, "dashed", 0.9))
    if bands:
        _draw_field(ax, field, bands, lines, colour)


def _draw_field(
    ax: Any,
    field: TubeField,
    bands: list[tuple[float, float, tuple[float, ...]]],
    lines: list[tuple[float, str, float]],
    colour: str,
) -> None:
    """The filled bands ``(lower_mm, upper_mm, rgba)`` (lower < distance <= upper) and the
    outlines ``(level_mm, style, width)`` of a tube field, each band and each level one path.

    The outlines' collection carries ``levels`` and ``filled`` as matplotlib's contour sets
    do (one path per level)."""
    gen = contour_generator(
        field.u_mm,
        field.v_mm,
        field.distance_mm,
        line_type=LineType.SeparateCode,
        fill_type=FillType.OuterCode,
    )
    fills, fill_colours = [], []
    for lower, upper, rgba in bands:
        path = _one_path(gen.filled(lower, upper))
        if path is not None:
            fills.append(path)
            fill_colours.append(rgba)
    if fills:
        filled = PathCollection(fills, facecolors=fill_colours, edgecolors="none", zorder=2)
        filled.levels, filled.filled = [b[1] for b in bands], True  # type: ignore[attr-defined]
        ax.add_collection(filled, autolim=False)
    outlines = [_one_path(gen.lines(level)) or Path(np.empty((0, 2))) for level, _, _ in lines]
    if lines:
        outline = PathCollection(
            outlines,
            facecolors="none",
            edgecolors=colour,
            linewidths=[w for _, _, w in lines],
            linestyles=[s for _, s, _ in lines],
            zorder=3,
        )
        outline.levels, outline.filled = [lv for lv, _, _ in lines], False  # type: ignore[attr-defined]
        ax.add_collection(outline, autolim=False)


def _one_path(pieces: Any) -> Path | None:
    """contourpy's ``(points, codes)`` lists (``SeparateCode`` lines or ``OuterCode`` fills)
    as one matplotlib path (None without pieces)."""
    points, codes = pieces
    if not len(points):
        return None
    return Path(np.concatenate(points), np.concatenate(codes))


def _draw_body(ax: Any, image: SliceImage, body: BodyDrawing, **style: Any) -> int:
    polys = revolved_section(plane_of(image), body.p0_lps, body.axis_lps, body.s_mm, body.r_mm)
    for poly in polys:  # add_artist: no data-limit update (ax.fill spends ~50 ms on it)
        ax.add_artist(Polygon(poly, closed=True, **style))
    return len(polys)


def _draw_trajectory(ax: Any, image: SliceImage, tr: TrajectoryDrawing) -> None:
    colour = CURRENT_COLOUR if tr.current else OTHER_COLOUR
    line = np.array([tr.entry_lps, tr.target_lps], dtype=np.float64)
    uv, near = polyline_in_plane(image, line, slab_mm=SLAB_MM)
    _line(
        ax,
        uv[:, 0],
        uv[:, 1],
        "-" if near.all() else "--",
        color=colour,
        lw=1.0 if tr.current else 0.8,
        alpha=0.9,
        zorder=4,
    )
    _draw_body(
        ax,
        image,
        tr.drill,
        facecolor=colour,
        edgecolor=colour,
        alpha=0.35 if tr.current else 0.3,
        lw=1.4 if tr.current else 1.1,
        zorder=4,
    )
    if tr.implant is not None:
        _draw_body(
            ax,
            image,
            tr.implant,
            fill=False,
            edgecolor=implant_colour(tr),
            lw=1.6 if tr.current or tr.offending else 1.0,
            zorder=5,
        )


def implant_colour(tr: TrajectoryDrawing) -> str:
    """The outline colour of a trajectory's implant: red with a plan problem."""
    if tr.offending:
        return VIOLATED_COLOUR
    return IMPLANT_COLOUR if tr.current else OTHER_COLOUR


def _draw_arch(ax: Any, image: SliceImage, arch_lps: np.ndarray) -> None:
    uv, off = image.to_plane_mm(np.atleast_2d(arch_lps))
    on = np.abs(off) <= SLAB_MM
    _line(ax, uv[:, 0], uv[:, 1], ":", color=ARCH_COLOUR, lw=1.2, zorder=6)
    solid = uv.copy()  # the segments with both ends on the slice, as one line broken by NaN
    solid[~on] = np.nan
    _line(ax, solid[:, 0], solid[:, 1], "-", color=ARCH_COLOUR, lw=1.8, zorder=6)
    _line(
        ax, uv[:, 0], uv[:, 1], "s", mfc="none", mec=ARCH_COLOUR, ms=7, mew=1.5, zorder=7, alpha=0.9
    )


def draw_scene(
    ax: Any, image: SliceImage, scene: OverlayScene, *, arch: bool = False
) -> dict[str, Any]:
    """Draw ``scene`` on ``ax`` (in-plane mm) and return the handle artists by name; the arch
    only when ``arch`` (the axial view)."""
    for lm in scene.landmarks:
        _draw_canal(ax, image, lm)
    for tr in sorted(scene.trajectories, key=lambda t: t.current):  # the current one on top
        _draw_trajectory(ax, image, tr)
    if arch and scene.arch_lps is not None and len(scene.arch_lps):
        _draw_arch(ax, image, scene.arch_lps)
    if scene.stop_lps is not None:
        suv, _ = image.to_plane_mm(np.asarray(scene.stop_lps, dtype=np.float64))
        _line(ax, [suv[0]], [suv[1]], "x", color=STOP_COLOUR, ms=9, mew=2, zorder=8)
    artists: dict[str, Any] = {}
    for name, pt in scene.handles.items():
        huv, off = image.to_plane_mm(pt)
        artists[name] = _line(
            ax,
            [huv[0]],
            [huv[1]],
            "o",
            mfc="none",
            mec=HANDLE_COLOURS[name],
            mew=2,
            ms=9,
            alpha=1.0 if abs(float(off)) <= SLAB_MM else 0.45,
            zorder=9,
        )
    return artists
