"""A matplotlib canvas' image kept as a background, its overlays drawn over it.

A slice view's Agg draw was half the image (resampled to the canvas, 3-6 ms a view) and half
its overlays. :class:`KeptBackground` renders the image alone once (while it, the view's limits
and the canvas' size stay), copies it (``copy_from_bbox``), and a draw that only the overlays
need restores that copy and draws the overlays over it, in the order and with the renderer
``Figure.draw`` and ``Axes.draw`` use: the same pixels as a full draw (tests/app/gui/
test_slice_blit.py). Anything a kept background could not stand for (another image or axes,
figure-level artists, a layout engine) gets matplotlib's own full draw.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from operator import attrgetter
from typing import Any

from matplotlib.backend_bases import DrawEvent
from matplotlib.image import AxesImage


class KeptBackground:
    """The kept image of one canvas (``canvas``: a ``FigureCanvasQTAgg`` whose figure holds
    the single axes ``ax`` with the image artist ``image`` under every other artist)."""

    def __init__(self) -> None:
        self._copy: Any = None
        self._drawn_for: tuple[Any, ...] | None = None
        #: Bumped by the owner whenever the image's pixels change (data, extent, window).
        self.image_version = 0
        #: Draws that restored the kept image (the overlays alone drawn), and full ones.
        self.blits = 0
        self.full_draws = 0

    def draw(self, canvas: Any, ax: Any, image: Any, full_draw: Callable[[], None]) -> None:
        """Agg-draw ``canvas``: the image from the kept copy when it, the limits and the
        canvas' size are as it was drawn for, else drawn anew (alone, then kept); then the
        overlays over it in ``Axes.draw``'s order (by zorder, then as added); then
        ``draw_event``, as ``Figure.draw`` sends it. ``full_draw``: the canvas' own draw
        (used when a kept image cannot stand for the figure). The caller asks Qt to paint."""
        overlays = self._overlays(canvas.figure, ax, image)
        if overlays is None:
            self._copy = None
            self.full_draws += 1
            full_draw()
            return
        canvas.renderer = renderer = canvas.get_renderer()
        fig = canvas.figure
        with getattr(fig, "_render_lock", contextlib.nullcontext()):  # as Figure.draw holds it
            if self._copy is not None and self._key(canvas, ax) == self._drawn_for:
                canvas.restore_region(self._copy)
                self.blits += 1
            else:  # Figure.draw without the overlays (Axes.draw skips animated artists)
                renderer.clear()
                fig.patch.draw(renderer)
                for artist in overlays:
                    artist.set_animated(True)
                try:
                    ax.draw(renderer)
                finally:
                    for artist in overlays:
                        artist.set_animated(False)
                self._copy = canvas.copy_from_bbox(fig.bbox)
                self._drawn_for = self._key(canvas, ax)
                self.full_draws += 1
            for artist in overlays:
                artist.draw(renderer)
            fig.stale = False
        canvas.callbacks.process("draw_event", DrawEvent("draw_event", canvas, renderer))

    def _key(self, canvas: Any, ax: Any) -> tuple[Any, ...]:
        """What the kept image was drawn for."""
        return (
            self.image_version,
            canvas.get_width_height(physical=True),
            canvas.figure.dpi,
            tuple(ax.get_xlim()),
            tuple(ax.get_ylim()),
            tuple(ax.get_position().bounds),
        )

    @staticmethod
    def _overlays(fig: Any, ax: Any, image: Any) -> list[Any] | None:
        """The artists over the image in the order ``Axes.draw`` draws them, or None when the
        figure holds anything else a kept image would not stand for (no image yet, another
        image, another axes, figure-level artists, a layout engine or axes locator)."""
        if image is None or fig.axes != [ax] or len(fig.get_children()) != 2:
            return None
        if fig.get_layout_engine() is not None or ax.get_axes_locator() is not None:
            return None
        ids = {id(a) for a in (*ax.lines, *ax.patches, *ax.collections, *ax.texts, *ax.artists)}
        children = ax.get_children()
        if any(isinstance(a, AxesImage) and a is not image for a in children):
            return None
        overlays = [a for a in children if id(a) in ids]
        if any(a.zorder < image.zorder or a.get_animated() for a in overlays):
            return None
        return sorted(overlays, key=attrgetter("zorder"))
