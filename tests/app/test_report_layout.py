"""The report's text pages: wrapped to the measured width, never cut, never past the page."""

from __future__ import annotations

import re

import numpy as np
from matplotlib.backends.backend_pdf import PdfFile, RendererPdf
from matplotlib.figure import Figure
from matplotlib.text import Text

from ctdrill.app.report.layout import (
    COLUMN_GAP_IN,
    MARGIN_IN,
    PAGE_IN,
    Column,
    TextPages,
    text_width_in,
    wrap,
)


def _texts(fig: object) -> list[Text]:
    return [t for t in fig.findobj(Text) if t.get_text()]  # type: ignore[attr-defined]


def pdf_renderer(fig: Figure) -> RendererPdf:
    """The renderer the PDF is written with (72 dpi: points), for ``fig`` set to it, so that
    text extents are those of the written PDF (Agg's raster extents include hinting)."""
    import io

    fig.set_dpi(72)
    w, h = fig.get_size_inches()
    return RendererPdf(PdfFile(io.BytesIO()), 72, h * 72, w * 72)


def test_measured_widths_match_matplotlibs_own_layout() -> None:
    fig = TextPages("t").figure()
    renderer = pdf_renderer(fig)
    for text in ("warning [plan_violates_margin]: 12.000 mm", "WWWW mmmm iiii", "µ ≥ ± é"):
        t = fig.text(0.1, 0.5, text, fontsize=9.0)
        drawn_in = t.get_window_extent(renderer).width / fig.dpi
        # advances without kerning: never narrower than written, at most 2 % wider
        assert drawn_in <= text_width_in(text, 9.0) * 1.001
        assert text_width_in(text, 9.0) <= drawn_in * 1.02


def test_wrap_keeps_every_character_and_each_line_fits() -> None:
    text = ("the planned path breaks the safety margin " * 12) + "x" * 400 + " end"
    lines = wrap(text, 3.0, 9.0)
    assert "".join(lines).replace(" ", "") == text.replace(" ", "")
    assert all(text_width_in(line, 9.0) <= 3.0 for line in lines)
    assert len(lines) > 10
    assert wrap("a\n\nb", 3.0, 9.0) == ["a", "", "b"]  # newlines kept


def test_pages_flow_and_nothing_leaves_the_page_or_its_column() -> None:
    pages = TextPages("report title")
    long = "warning [x]: " + "clearance at the planned depth 12.000 mm to 'canal' " * 40
    for _ in range(6):
        pages.paragraph(long, size_pt=9.0)
    columns = (Column("name", 1.0), Column("a long heading over a narrow column", 0.5))
    rows = [[f"trajectory {k} " + "y" * 200, f"{k}.000 " * 6] for k in range(40)]
    pages.table(columns, rows)
    figs = pages.finish()
    assert len(figs) >= 4
    width = PAGE_IN[0] - MARGIN_IN[0] - MARGIN_IN[1]
    col_edges = np.cumsum([0.0, width * 1.0 / 1.5, width * 0.5 / 1.5]) + MARGIN_IN[0]
    seen = ""
    for k, fig in enumerate(figs, start=1):
        renderer = pdf_renderer(fig)
        texts = _texts(fig)
        assert texts[0].get_text() == "report title"
        assert any(t.get_text() == f"page {k} of {len(figs)}" for t in texts)
        for t in texts:
            box = t.get_window_extent(renderer)
            x0, x1 = box.x0 / fig.dpi, box.x1 / fig.dpi
            y0, y1 = box.y0 / fig.dpi, box.y1 / fig.dpi
            assert MARGIN_IN[0] - 0.01 <= x0 and x1 <= PAGE_IN[0] - MARGIN_IN[1] + 0.01, t
            assert y0 >= 0.2 and y1 <= PAGE_IN[1] - MARGIN_IN[2] + 0.2, t
            if re.fullmatch(r"(trajectory \d+ ?)?y*|(\d+\.000 ?)+", t.get_text()):  # a cell
                col = int(np.searchsorted(col_edges, x0 + 1e-6)) - 1
                assert x1 <= col_edges[col + 1] - COLUMN_GAP_IN + 0.01, t.get_text()
            seen += t.get_text()
    # the heading is repeated on each page the table spans; every row is there whole
    assert seen.count("a long") >= 2
    for k in range(40):
        assert f"trajectory{k}" + "y" * 200 in seen.replace(" ", "")
    assert seen.replace(" ", "").count("clearanceattheplanneddepth") == 6 * 40
