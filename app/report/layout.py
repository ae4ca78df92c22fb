"""Pages of text and tables for the report: flowed top to bottom, wrapped, never cut off.

A :class:`TextPages` writes lines and table rows onto A4 landscape matplotlib figures, starting
a new page when the next block does not fit. Text is wrapped to the width it has
(:func:`wrap`, by the font's measured glyph widths, so a wrapped line never runs past its
column or the page); a single word longer than a line is broken, never dropped. Every string
is a text object of its own, so the PDF's text can be extracted (tests read the table back).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from ctdrill.text import printable

#: A4 landscape, inches.
PAGE_IN = (11.69, 8.27)
#: Page margins, inches: left, right, top, bottom.
MARGIN_IN = (0.6, 0.6, 0.55, 0.5)
#: Line height as a multiple of the font size.
LINE_SPACING = 1.3
#: Space between a table's columns, inches.
COLUMN_GAP_IN = 0.12


_ADVANCE_EM: dict[tuple[str, bool], float] = {}


def text_width_in(text: str, size_pt: float, *, bold: bool = False) -> float:
    """Width of ``text`` set in the report's font (matplotlib's default, DejaVu Sans) at
    ``size_pt``, inches: the sum of the glyphs' advances (kerning, at most a few hundredths
    of an em per pair, only ever narrows DejaVu's text)."""
    from matplotlib.font_manager import FontProperties, findfont, get_font
    from matplotlib.ft2font import LoadFlags

    font = None
    em = 0.0
    for ch in text:
        key = (ch, bold)
        if key not in _ADVANCE_EM:
            if font is None:
                font = get_font(findfont(FontProperties(weight="bold" if bold else "normal")))
                font.set_size(100.0, 72)
            glyph = font.load_char(ord(ch), flags=LoadFlags.NO_HINTING)
            _ADVANCE_EM[key] = glyph.linearHoriAdvance / 65536.0 / 100.0
        em += _ADVANCE_EM[key]
    return em * size_pt / 72.0


def wrap(text: str, width_in: float, size_pt: float, *, bold: bool = False) -> list[str]:
    """``text`` (printable, newlines kept) wrapped to lines no wider than ``width_in`` inches
    at ``size_pt``; a word longer than a line is broken, never dropped."""
    out: list[str] = []
    for para in printable(text).split("\n"):
        line = ""
        for word in para.split(" "):
            candidate = word if not line else f"{line} {word}"
            if text_width_in(candidate, size_pt, bold=bold) <= width_in:
                line = candidate
                continue
            if line:
                out.append(line)
            line = ""
            while text_width_in(word, size_pt, bold=bold) > width_in and len(word) > 1:
                n = len(word)
                while n > 1 and text_width_in(word[:n], size_pt, bold=bold) > width_in:
                    n -= 1
                out.append(word[:n])
                word = word[n:]
            line = word
        out.append(line)
    return out


@dataclass(frozen=True)
class Column:
    """A table column: its heading and its share of the table's width."""

    heading: str
    share: float


class TextPages:
    """Figures (pages) filled top to bottom with wrapped text and table rows.

    Parameters
    ----------
    title : drawn at the top of every page, with the page's number in the document added by
        :meth:`finish` (``title - page k``).
    """

    def __init__(self, title: str) -> None:
        self.title = printable(title)
        self.pages: list[Figure] = []
        self._y_in = 0.0
        self._fig: Figure | None = None

    @property
    def width_in(self) -> float:
        """Width of the text area, inches."""
        return PAGE_IN[0] - MARGIN_IN[0] - MARGIN_IN[1]

    def _new_page(self) -> Figure:
        fig = Figure(figsize=PAGE_IN)
        self.pages.append(fig)
        self._fig = fig
        self._y_in = MARGIN_IN[2]
        self._text(MARGIN_IN[0], self.title, 9.0, colour="#555555")
        self._y_in += 9.0 * LINE_SPACING / 72.0 + 0.1
        return fig

    def _room_in(self) -> float:
        return PAGE_IN[1] - MARGIN_IN[3] - self._y_in

    def _need(self, height_in: float) -> Figure:
        """The current page if ``height_in`` fits on it, else a new one."""
        if self._fig is None or height_in > self._room_in():
            return self._new_page()
        return self._fig

    def _text(
        self, x_in: float, text: str, size_pt: float, *, bold: bool = False, colour: str = "k"
    ) -> None:
        assert self._fig is not None
        self._fig.text(
            x_in / PAGE_IN[0],
            1.0 - self._y_in / PAGE_IN[1],
            text,
            fontsize=size_pt,
            fontweight="bold" if bold else "normal",
            color=colour,
            va="top",
            ha="left",
        )

    def gap(self, height_in: float) -> None:
        """Vertical space (dropped at the top of a page)."""
        if self._fig is not None and height_in < self._room_in():
            self._y_in += height_in

    def paragraph(
        self,
        text: str,
        *,
        size_pt: float = 9.0,
        bold: bool = False,
        colour: str = "k",
        indent_in: float = 0.0,
        keep_with_next_in: float = 0.0,
    ) -> None:
        """``text`` wrapped to the page width, as many pages as it takes (line by line)."""
        step = size_pt * LINE_SPACING / 72.0
        lines = wrap(text, self.width_in - indent_in, size_pt, bold=bold)
        for n, line in enumerate(lines):
            extra = keep_with_next_in if n == len(lines) - 1 else 0.0
            self._need(step + extra)
            self._text(MARGIN_IN[0] + indent_in, line, size_pt, bold=bold, colour=colour)
            self._y_in += step

    def table(
        self, columns: Sequence[Column], rows: Sequence[Sequence[str]], *, size_pt: float = 8.0
    ) -> None:
        """A table: a bold heading row (repeated on each page it spans), then ``rows``, each
        cell wrapped to its column; a row never splits across pages."""
        total = sum(c.share for c in columns)
        widths = [self.width_in * c.share / total for c in columns]
        xs = [MARGIN_IN[0] + sum(widths[:k]) for k in range(len(widths))]
        step = size_pt * LINE_SPACING / 72.0

        def cells(values: Sequence[str], bold: bool = False) -> list[list[str]]:
            return [
                wrap(v, w - COLUMN_GAP_IN, size_pt, bold=bold)
                for v, w in zip(values, widths, strict=True)
            ]

        head = cells([c.heading for c in columns], bold=True)
        head_h = max(len(c) for c in head) * step + 0.06

        def draw(block: list[list[str]], bold: bool) -> None:
            for x, lines in zip(xs, block, strict=True):
                for n, line in enumerate(lines):
                    y = self._y_in
                    self._y_in += n * step
                    self._text(x, line, size_pt, bold=bold)
                    self._y_in = y
            self._y_in += max(len(c) for c in block) * step
            self._rule()

        page: Figure | None = None
        for row in rows:
            body = cells(row)
            row_h = max(len(c) for c in body) * step + 0.06
            fig = self._need(head_h + row_h if page is not self._fig else row_h)
            if fig is not page:
                page = fig
                draw(head, True)
            draw(body, False)

    def _rule(self) -> None:
        assert self._fig is not None
        y = 1.0 - (self._y_in + 0.02) / PAGE_IN[1]
        x0 = MARGIN_IN[0] / PAGE_IN[0]
        self._fig.add_artist(
            _line([x0, x0 + self.width_in / PAGE_IN[0]], [y, y], self._fig)  # full width
        )
        self._y_in += 0.06

    def remaining_figure(self, min_height_in: float) -> tuple[Figure, float, float]:
        """The current page and the band left on it for a drawing, ``(figure, top_in,
        height_in)`` from the page's top (a new page when less than ``min_height_in`` is
        left); nothing flows onto that page afterwards."""
        fig = self._need(min_height_in)
        top, height = self._y_in, self._room_in()
        self._y_in = PAGE_IN[1]
        return fig, top, height

    def new_page(self) -> None:
        """Start a fresh page that text flows onto (a chapter's first page)."""
        self._new_page()

    def figure(self) -> Figure:
        """A fresh page of its own (for a drawing), titled like the others."""
        fig = self._new_page()
        self._y_in = PAGE_IN[1]  # nothing flows onto it
        return fig

    def finish(self) -> list[Figure]:
        """The pages, each numbered ``page k of n``."""
        n = len(self.pages)
        for k, fig in enumerate(self.pages, start=1):
            fig.text(
                1.0 - MARGIN_IN[1] / PAGE_IN[0],
                0.25 / PAGE_IN[1],
                f"page {k} of {n}",
                fontsize=8,
                color="#555555",
                ha="right",
                va="bottom",
            )
        return list(self.pages)


def _line(x: list[float], y: list[float], fig: Figure) -> Line2D:
    return Line2D(x, y, transform=fig.transFigure, color="#999999", lw=0.5)
