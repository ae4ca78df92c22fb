"""The whole report: inputs read and computed as ``ctdrill export`` does, pages drawn off
screen, the PDF written atomically.

Order of the pages: the summary (the case, the table of every trajectory, each one's lines and
warnings, the signature block), a clinical page per implant (:mod:`ctdrill.app.report.clinical`)
with its zoomed cross-section and panoramic (:mod:`ctdrill.app.report.implant_view`); with
``--appendix`` then the panoramic reformat with every implant, a cross-section per trajectory,
the 3D view, the engineering detail (calibrations, force terms) and each trajectory's curves.
Everything is computed and drawn in memory first; the file appears whole (a temporary sibling
renamed over it) or not at all.
"""

from __future__ import annotations

import io
import time
from collections.abc import Callable, Sequence
from pathlib import Path

from matplotlib.figure import Figure

from ctdrill.app.records import atomic_write_bytes
from ctdrill.app.report.clinical import appendix_pages, clinical_pages, signature_block
from ctdrill.app.report.curves import curves_page
from ctdrill.app.report.entries import Entry, drawn_entries, report_entries
from ctdrill.app.report.layout import TextPages
from ctdrill.app.report.summary import summary_pages
from ctdrill.app.report.timing import Timings
from ctdrill.engine.case import PreparedCase, prepare_case
from ctdrill.engine.settings import DEFAULTS, ExportSettings
from ctdrill.text import printable

#: The document's title (every page's header).
TITLE = "ctdrill report: planned implant osteotomy"


def _plan_files(case: PreparedCase) -> list[str]:
    seen: list[str] = []
    for plan in case.plans:
        name = printable(Path(plan.source).name) if plan.source else plan.name
        if name not in seen:
            seen.append(name)
    return seen


def report_pages(
    case: PreparedCase,
    entries: Sequence[Entry],
    *,
    timings: Timings | None = None,
    views: Callable[[TextPages, PreparedCase, Sequence[Entry], Timings], None] | None = None,
    appendix: bool = False,
) -> list[Figure]:
    """Every page of the report, drawn (not yet written): the clinical summary (the case's
    page with the signature block, a page per implant with its zoomed views); with
    ``appendix`` also the full panoramic, every cross-section, the 3D view, the engineering
    detail and the force curves."""
    t = timings if timings is not None else Timings()
    pages = TextPages(TITLE)
    t0 = time.perf_counter()
    summary_pages(
        pages,
        case.volume,
        entries,
        include_phi=case.settings.include_phi,
        plan_files=_plan_files(case),
    )
    signature_block(pages)
    clinical_pages(pages, case, entries)
    t.add("summary", time.perf_counter() - t0)
    if not appendix:
        return pages.finish()
    if views is None:
        from ctdrill.app.report.views import view_pages

        views = view_pages
    views(pages, case, entries, t)
    t0 = time.perf_counter()
    appendix_pages(pages, entries)
    for entry in drawn_entries(entries):
        curves_page(pages.figure(), entry)
    t.add("curves", time.perf_counter() - t0)
    return pages.finish()


def pdf_bytes(figures: Sequence[Figure]) -> bytes:
    """The PDF of ``figures``, one page each, with no date or identifier in its metadata
    (the same inputs give the same bytes)."""
    from matplotlib.backends.backend_pdf import PdfPages

    buf = io.BytesIO()
    meta = {"Title": TITLE, "Creator": "ctdrill report", "Producer": "ctdrill (matplotlib)"}
    with PdfPages(buf, metadata={**meta, "CreationDate": None}) as pdf:
        for fig in figures:
            pdf.savefig(fig)
    return buf.getvalue()


def write_report(
    dicom: Path,
    plan_paths: Sequence[Path],
    out: Path,
    settings: ExportSettings = DEFAULTS,
    *,
    progress: Callable[[int, int, str], None] | None = None,
    timings: Timings | None = None,
    appendix: bool = False,
) -> tuple[Path, int]:
    """Compute the case as ``ctdrill export`` does with ``settings`` and write its report to
    ``out`` (PDF); ``timings`` collects the seconds of each stage.

    Returns
    -------
    The written path and its number of pages.

    Raises
    ------
    AppInputError, EngineInputError, ImagingInputError, ModelInputError
        Bad input (one line naming the file or field); ``out`` is then untouched.
    """
    from ctdrill.app.errors import AppInputError

    if Path(out).is_dir():
        raise AppInputError(f"--out {out}: is a folder; give the PDF's file name")
    t = timings if timings is not None else Timings()
    t0 = time.perf_counter()
    case = prepare_case(dicom, plan_paths, settings, progress=progress)
    t.add("load and compute", time.perf_counter() - t0)
    t0 = time.perf_counter()
    entries = report_entries(case)
    t.add("summaries", time.perf_counter() - t0)
    figures = report_pages(case, entries, timings=t, appendix=appendix)
    t0 = time.perf_counter()
    data = pdf_bytes(figures)
    t.add("pdf", time.perf_counter() - t0)
    t0 = time.perf_counter()
    path = atomic_write_bytes(out, data, what="--out")
    t.add("write", time.perf_counter() - t0)
    return path, len(figures)
