"""A :class:`~ctdrill.app.force_figure.ForceFigure` rasterised with Pillow (``force.png``).

matplotlib draws the same figure for the report (:func:`ctdrill.app.export_plot.draw_force_figure`);
this renderer exists because importing matplotlib and building a figure cost a fresh
``ctdrill export`` of one plan about 0.5 s of CPU, more than all of its work. It follows
matplotlib's look where it matters for reading the plot: DejaVu Sans (matplotlib's own font
file, found without importing matplotlib), 10 pt tick labels, ticks at 1, 2, 2.5 or 5 times a
power of ten, the panels' layout and the legends in their corners. Everything is drawn at
:data:`SUPERSAMPLE` times the size and reduced by averaging, which smooths lines and edges.
"""

from __future__ import annotations

import functools
import importlib.util
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ctdrill.app.force_figure import Coords, ForceFigure, Panel, Rule, Text

if TYPE_CHECKING:
    from PIL import ImageDraw, ImageFont

#: Pixels per inch of the output (sizes in points are converted at this).
DPI = 150
#: Drawn at this multiple of the output size, then reduced (anti-aliasing).
SUPERSAMPLE = 2
#: Axes placement (figure fractions): room for 5-character tick labels and the axis label on
#: the left, the stop label above the top panel and the title.
MARGINS = {"left": 0.095, "right": 0.975, "bottom": 0.075, "top": 0.915, "hspace": 0.14}
#: Axis label positions (panel fractions): left of the widest tick labels, below the x ones.
YLABEL_AT = (-0.075, 0.5)
XLABEL_AT = (0.5, -0.2)
#: Tick labels and axis labels (points); the title.
TICK_PT = 10.0
TITLE_PT = 9.0
#: Most intervals between ticks on the depth axis and on each panel's value axis.
X_BINS = 9
Y_BINS = 6
#: Frame and tick lines (points): width, tick length, gap between tick and label.
FRAME_PT = 0.8
TICK_LEN_PT = 3.5
TICK_PAD_PT = 3.5
GRID_RGBA = (176, 176, 176, 77)  # matplotlib's grid colour at alpha 0.3
#: Dash patterns (on, off) in multiples of the line width, as matplotlib's.
DASHES = {"--": (3.7, 1.6), ":": (1.0, 1.65)}


def _px(pt: float) -> float:
    """Points to pixels of the supersampled canvas."""
    return pt * DPI / 72.0 * SUPERSAMPLE


@functools.cache
def _font_file() -> str | None:
    spec = importlib.util.find_spec("matplotlib")  # the file only: matplotlib is not imported
    for folder in spec.submodule_search_locations or () if spec else ():
        path = Path(folder) / "mpl-data" / "fonts" / "ttf" / "DejaVuSans.ttf"
        if path.is_file():
            return str(path)
    return None  # pragma: no cover - matplotlib is a dependency


@functools.cache
def _font(size_pt: float) -> ImageFont.FreeTypeFont | ImageFont.ImageFont:
    from PIL import ImageFont

    size = max(1, round(_px(size_pt)))
    path = _font_file()
    if path is None:  # pragma: no cover - matplotlib is a dependency
        return ImageFont.load_default(size)
    return ImageFont.truetype(path, size)


def _rgb(colour: str, alpha: float = 1.0) -> tuple[int, int, int, int]:
    c = colour.lstrip("#")
    return (int(c[0:2], 16), int(c[2:4], 16), int(c[4:6], 16), round(255 * alpha))


def nice_ticks(lo: float, hi: float, bins: int) -> tuple[np.ndarray, int]:
    """Ticks within ``[lo, hi]`` at multiples of the smallest step of 1, 2, 2.5 or 5 times a
    power of ten that is at least ``(hi - lo) / bins`` (a smaller one where that leaves fewer
    than two ticks), and the decimals that print every tick exactly: matplotlib's default
    locator and formatter."""
    span = hi - lo
    if not (math.isfinite(span) and span > 0):
        return np.array([lo]), 0
    raw = span / bins
    steps = [(m, p) for p in range(math.floor(math.log10(raw)) - 1, math.floor(math.log10(raw)) + 2)
             for m in (1.0, 2.0, 2.5, 5.0)]  # fmt: skip
    k = next(i for i, (m, p) in enumerate(steps) if m * 10.0**p >= raw)
    while True:
        mantissa, power = steps[k]
        step = mantissa * 10.0**power
        ticks = np.arange(math.floor(lo / step) - 1, math.ceil(hi / step) + 2) * step
        ticks = ticks[(ticks >= lo) & (ticks <= hi)]
        if ticks.size >= 2 or k == 0:
            break
        k -= 1
    decimals = max(0, -power + (1 if mantissa == 2.5 else 0))
    return ticks, decimals


def _label(value: float, decimals: int) -> str:
    text = f"{value:.{decimals}f}"
    if text.lstrip("-").strip("0.") == "":
        text = text.lstrip("-")  # no "-0"
    return text.replace("-", "\u2212")  # matplotlib's minus sign


class _Box:
    """A panel's pixel box on the canvas and its data limits."""

    def __init__(self, x0: float, y0: float, x1: float, y1: float, xlim: Any, ylim: Any):
        self.x0, self.y0, self.x1, self.y1 = x0, y0, x1, y1
        self.xlim, self.ylim = xlim, ylim

    def x(self, v: Any) -> Any:
        lo, hi = self.xlim
        return self.x0 + (np.asarray(v, dtype=np.float64) - lo) / (hi - lo) * (self.x1 - self.x0)

    def y(self, v: Any) -> Any:
        lo, hi = self.ylim
        return self.y1 - (np.asarray(v, dtype=np.float64) - lo) / (hi - lo) * (self.y1 - self.y0)

    def at(self, t: Text) -> tuple[float, float]:
        fx = lambda v: self.x0 + v * (self.x1 - self.x0)  # noqa: E731
        fy = lambda v: self.y1 - v * (self.y1 - self.y0)  # noqa: E731
        kinds: dict[Coords, tuple[float, float]] = {
            "data": (float(self.x(t.x)), float(self.y(t.y))),
            "axes": (fx(t.x), fy(t.y)),
            "xdata": (float(self.x(t.x)), fy(t.y)),
            "ydata": (fx(t.x), float(self.y(t.y))),
        }
        return kinds[t.coords]


_ANCHOR_H = {"left": "l", "center": "m", "right": "r"}
_ANCHOR_V = {"bottom": "d", "center": "m", "top": "a", "baseline": "s"}


def _text(draw: ImageDraw.ImageDraw, xy: tuple[float, float], t: Text) -> None:
    anchor = _ANCHOR_H[t.ha] + _ANCHOR_V[t.va]
    draw.text(xy, t.text, fill=_rgb(t.colour), font=_font(t.size_pt), anchor=anchor)


def _runs(x: np.ndarray, y: np.ndarray) -> list[np.ndarray]:
    """Runs of finite points as (n, 2) pixel arrays (a NaN breaks a line, as matplotlib's)."""
    pts = np.stack([x, y], axis=1)
    ok = np.isfinite(pts).all(axis=1)
    breaks = np.flatnonzero(np.diff(ok.astype(np.int8)) != 0) + 1
    return [run for run in np.split(pts, breaks) if run.shape[0] and np.isfinite(run[0]).all()]


def _rule(draw: ImageDraw.ImageDraw, box: _Box, r: Rule) -> None:
    width = max(1, round(_px(r.width_pt)))
    if r.vertical:
        a = float(box.x(r.at))
        start, end = box.y0, box.y1
    else:
        a = float(box.y(r.at))
        start, end = box.x0, box.x1
    if not math.isfinite(a):
        return
    on, off = DASHES.get(r.style, (0.0, 0.0))
    step = [(start, end)]
    if on:
        on_px, off_px = on * _px(r.width_pt), off * _px(r.width_pt)
        pos = np.arange(start, end, on_px + off_px)
        step = [(p, min(p + on_px, end)) for p in pos.tolist()]
    for p, q in step:
        seg = [(a, p), (a, q)] if r.vertical else [(p, a), (q, a)]
        draw.line(seg, fill=_rgb(r.colour), width=width)


def _panel(draw: ImageDraw.ImageDraw, box: _Box, panel: Panel, x_ticks: np.ndarray) -> None:
    """The clipped content of one panel (drawn on a canvas the size of the panel's box)."""
    for s in panel.spans:
        y_hi, y_lo = float(box.y(s.hi)), float(box.y(s.lo))
        draw.rectangle([box.x0, y_hi, box.x1, y_lo], fill=_rgb(s.colour, s.alpha))
    for f in panel.fills:
        for run_hi, run_lo in zip(
            _runs(box.x(f.x), box.y(f.hi)), _runs(box.x(f.x), box.y(f.lo)), strict=False
        ):
            poly = np.concatenate([run_hi, run_lo[::-1]])
            colour = _rgb(f.colour, f.alpha)
            draw.polygon([tuple(p) for p in poly.tolist()], fill=colour)
            if f.edge_pt:
                w = max(1, round(_px(f.edge_pt)))
                for edge in (run_hi, run_lo):
                    draw.line([tuple(p) for p in edge.tolist()], fill=colour, width=w)
    grid_w = max(1, round(_px(FRAME_PT)))
    y_ticks, _ = nice_ticks(*panel.ylim, Y_BINS)
    for v in box.x(x_ticks).tolist():
        draw.line([(v, box.y0), (v, box.y1)], fill=GRID_RGBA, width=grid_w)
    for v in box.y(y_ticks).tolist():
        draw.line([(box.x0, v), (box.x1, v)], fill=GRID_RGBA, width=grid_w)
    for ln in panel.lines:
        w = max(1, round(_px(ln.width_pt)))
        for run in _runs(box.x(ln.x), box.y(ln.y)):
            draw.line(
                [tuple(p) for p in run.tolist()], fill=_rgb(ln.colour), width=w, joint="curve"
            )
    for r in panel.rules:
        _rule(draw, box, r)


def _legend(draw: ImageDraw.ImageDraw, box: _Box, panel: Panel, size_pt: float) -> None:
    """matplotlib's legend in the panel's upper corner: a swatch (filled box or line) and a
    label per labelled fill and line, in a light frame."""
    entries: list[tuple[str, str, float, float]] = [
        (f.label, f.colour, f.alpha, 0.0) for f in panel.fills if f.label
    ]
    entries += [(ln.label, ln.colour, 1.0, ln.width_pt) for ln in panel.lines if ln.label]
    if not panel.legend or not entries:
        return
    font = _font(size_pt)
    em = _px(size_pt)
    pad, gap, handle, text_pad = 0.4 * em, 0.5 * em, 2.0 * em, 0.8 * em
    widths = [draw.textlength(label, font=font) for label, *_ in entries]
    w = 2 * pad + handle + text_pad + max(widths) + 0.4 * em
    h = 2 * pad + len(entries) * em + (len(entries) - 1) * gap
    inset = 0.5 * em
    x0 = box.x1 - inset - w if panel.legend == "upper right" else box.x0 + inset
    y0 = box.y0 + inset
    frame_w = max(1, round(_px(FRAME_PT)))
    draw.rounded_rectangle(
        [x0, y0, x0 + w, y0 + h], radius=0.2 * em, fill=(255, 255, 255, 204),
        outline=(204, 204, 204, 204), width=frame_w,
    )  # fmt: skip
    for k, (label, colour, alpha, line_pt) in enumerate(entries):
        mid = y0 + pad + k * (em + gap) + em / 2
        hx = x0 + pad + 0.2 * em
        if line_pt:
            width = max(1, round(_px(line_pt)))
            draw.line([(hx, mid), (hx + handle, mid)], fill=_rgb(colour), width=width)
        else:
            draw.rectangle(
                [hx, mid - 0.35 * em, hx + handle, mid + 0.35 * em], fill=_rgb(colour, alpha)
            )
        draw.text((hx + handle + text_pad, mid), label, fill=(0, 0, 0), font=font, anchor="lm")


def _ylabel(canvas: Any, text: str, right: float, mid: float) -> None:
    """``text`` rotated a quarter turn, its right edge (the text's bottom) at ``right``,
    centred on ``mid``."""
    from PIL import Image, ImageDraw

    font = _font(TICK_PT)
    left, top, right_, bottom = font.getbbox(text, anchor="ld")
    mask = Image.new("L", (int(right_ - left) + 2, int(bottom - top) + 2), 0)
    ImageDraw.Draw(mask).text((1 - left, 1 - top), text, fill=255, font=font, anchor="ld")
    mask = mask.rotate(90, expand=True)
    canvas.paste((0, 0, 0), (round(right - mask.width), round(mid - mask.height / 2)), mask)


def render(figure: ForceFigure, size_px: tuple[int, int]) -> np.ndarray:
    """``figure`` as an (H, W, 3) uint8 RGB image of ``size_px`` (width, height) pixels."""
    from PIL import Image, ImageDraw

    width, height = size_px[0] * SUPERSAMPLE, size_px[1] * SUPERSAMPLE
    canvas = Image.new("RGB", (width, height), (255, 255, 255))
    draw = ImageDraw.Draw(canvas, "RGBA")
    m = MARGINS
    n = len(figure.panels)
    panel_h = (m["top"] - m["bottom"]) / (n + (n - 1) * m["hspace"]) * height
    x0, x1 = m["left"] * width, m["right"] * width
    x_ticks, x_dec = nice_ticks(*figure.xlim, X_BINS)
    tick_font, frame_w = _font(TICK_PT), max(1, round(_px(FRAME_PT)))
    tick_len, tick_pad = _px(TICK_LEN_PT), _px(TICK_PAD_PT)
    top = (1.0 - m["top"]) * height
    for k, panel in enumerate(figure.panels):
        y0 = top + k * panel_h * (1.0 + m["hspace"])
        box = _Box(x0, y0, x1, y0 + panel_h, figure.xlim, panel.ylim)
        # the panel's content on its own canvas: clipped to the box, as matplotlib's
        inner = Image.new("RGB", (round(x1 - x0), round(panel_h)), (255, 255, 255))
        local = _Box(0.0, 0.0, x1 - x0, panel_h, figure.xlim, panel.ylim)
        _panel(ImageDraw.Draw(inner, "RGBA"), local, panel, x_ticks)
        canvas.paste(inner, (round(x0), round(y0)))
        draw.rectangle([x0, box.y0, x1, box.y1], outline=(0, 0, 0), width=frame_w)
        y_ticks, y_dec = nice_ticks(*panel.ylim, Y_BINS)
        for v, py in zip(y_ticks.tolist(), box.y(y_ticks).tolist(), strict=True):
            draw.line([(x0 - tick_len, py), (x0, py)], fill=(0, 0, 0), width=frame_w)
            label = _label(v, y_dec)
            draw.text(
                (x0 - tick_len - tick_pad, py), label, fill=(0, 0, 0), font=tick_font, anchor="rm"
            )
        for v, px in zip(x_ticks.tolist(), box.x(x_ticks).tolist(), strict=True):
            draw.line([(px, box.y1), (px, box.y1 + tick_len)], fill=(0, 0, 0), width=frame_w)
            if k == n - 1:
                at = (px, box.y1 + tick_len + tick_pad)
                draw.text(at, _label(v, x_dec), fill=(0, 0, 0), font=tick_font, anchor="ma")
        _legend(draw, box, panel, figure.legend_pt)
        for t in panel.texts:
            _text(draw, box.at(t), t)
        right = x0 + YLABEL_AT[0] * (x1 - x0)
        _ylabel(canvas, panel.ylabel, right, box.y0 + (1.0 - YLABEL_AT[1]) * panel_h)
        if k == n - 1:
            at = (x0 + XLABEL_AT[0] * (x1 - x0), box.y1 - XLABEL_AT[1] * panel_h)
            draw.text(at, figure.xlabel, fill=(0, 0, 0), font=tick_font, anchor="ma")
    title = Text(0.5, 0.985, figure.title, "axes", TITLE_PT, ha="center", va="top")
    _text(draw, (0.5 * width, (1.0 - 0.985) * height), title)
    return np.asarray(canvas.reduce(SUPERSAMPLE))
