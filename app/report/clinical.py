"""The report's clinical page of each implant, and the engineering appendix.

**Per implant** (:func:`clinical_pages`), a page a colleague can use: the site (FDI), the
implant and its drilling protocol with each drill's drilled depth, the angulation to the
patient's vertical, the implant-to-nerve distance against its margin, the thinnest bone walls
(buccal and lingual where the plan gives an arch), the bone height from the crest to the canal
along the axis, where the final drill stops, and the implant's warnings. The values are
:func:`ctdrill.engine.implant_facts.implant_facts` (headless); this module only words them.
Clearances and walls are printed with the digits the CT supports
(:func:`~ctdrill.imaging.resolution.format_clearance_mm`), depths to 0.01 mm.

**Appendix** (:func:`appendix_pages`): the engineering detail the clinical pages leave out:
each trajectory's calibration and how it was obtained, the force terms (peak and mean force,
the 68 % band, the share of extrapolated samples), the grey map; the force curves follow it.
"""

from __future__ import annotations

from collections.abc import Sequence

from ctdrill.app.report.entries import Entry, drawn_entries
from ctdrill.app.report.layout import Column, TextPages
from ctdrill.app.summary_lines import band_line, calibration_line
from ctdrill.engine.case import PreparedCase
from ctdrill.engine.implant_facts import ImplantFacts, implant_facts
from ctdrill.engine.stop import stop_words
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.resolution import format_clearance_mm
from ctdrill.warning_codes import banner_codes

#: The codes a clinical page lists (the window's banner problems).
BANNER = frozenset(banner_codes())

#: The clinical table's columns.
ITEM_COLUMNS = (Column("item", 1.0), Column("value", 3.2))
#: The protocol table's columns.
DRILL_COLUMNS = (
    Column("drill", 0.5),
    Column("diameter (mm)", 0.9),
    Column("tip length (mm)", 0.9),
    Column("drilled depth (mm)", 1.0),
    Column("beyond the apex (mm)", 1.0),
    Column("clearance (mm)", 1.1),
    Column("verdict", 1.6),
)
#: The signature block's lines.
SIGNATURE = (
    "Planned by: ______________________",
    "Date: ______________",
    "Approved by: ______________________",
)
#: The appendix table's columns.
APPENDIX_COLUMNS = (
    Column("trajectory", 1.3),
    Column("calibration", 1.2),
    Column("peak force (N)", 0.9),
    Column("mean force (N)", 0.9),
    Column("peak mean force (N), 68 % band", 1.6),
    Column("extrapolated samples", 1.0),
)


def _mm(value: float | None, facts: ImplantFacts) -> str:
    """A clearance or wall with the CT's digits, or ``unknown``."""
    return "unknown" if value is None else f"{format_clearance_mm(value, facts.accuracy_mm)} mm"


def implant_items(
    facts: ImplantFacts,
    stop_text: str,
    budget_mm: float | None = None,
    placement: str = "",
    tooth_mm: float | None = None,
) -> list[tuple[str, str]]:
    """The clinical page's (item, value) rows of ``facts``; ``stop_text`` says where the final
    drill stops; ``budget_mm`` the margin budget (placement ``placement``), when known."""
    site = facts.site_text or "not given (plan key site: an FDI tooth number 11-48)"
    nerve = "no landmark in the plan"
    if facts.nerve is not None and facts.nerve_mm is not None:
        verdict = (
            "keeps the margin"
            if facts.nerve_margin_mm is None or facts.nerve_mm >= facts.nerve_margin_mm
            else "INSIDE THE SAFETY MARGIN"
        )
        nerve = (
            f"{_mm(facts.nerve_mm, facts)} from the implant body to {facts.nerve!r} "
            f"(margin {facts.nerve_margin_mm:g} mm): {verdict}"
        )
    walls = f"thinnest {_mm(facts.min_wall_mm, facts)}"
    if facts.buccal_mm is not None or facts.lingual_mm is not None:
        walls += f"; buccal {_mm(facts.buccal_mm, facts)}, lingual {_mm(facts.lingual_mm, facts)}"
    else:
        walls += " (buccal and lingual need a dental arch in the plan)"
    height = "unknown (no canal landmark, or the crest is not found on the axis)"
    if facts.bone_height_mm is not None:
        height = (
            f"{_mm(facts.bone_height_mm, facts)} (crest at {facts.crest_depth_mm:.2f} mm, "
            f"canal at {facts.canal_depth_mm:.2f} mm from the entry"
            + (
                ")"
                if facts.axis_meets_canal
                else "; the axis passes beside the canal: its nearest approach)"
            )
        )
    return [
        ("site", site),
        (
            "implant",
            f"{facts.implant} ({facts.size_text}), apex {facts.apex_depth_mm:.2f} mm "
            "from the entry",
        ),
        ("angulation", f"{facts.angulation_deg:.1f} deg to the patient's vertical"),
        ("implant to nerve", nerve),
        ("bone walls", walls),
        ("bone height, crest to canal along the axis", height),
        (
            "nearest tooth",
            "none within 25 mm (teeth: CT numbers >= 2000 HU; docs/plan.md, Teeth)"
            if tooth_mm is None
            else f"{_mm(tooth_mm, facts)} from the implant body"
            + (" (INSIDE A TOOTH)" if tooth_mm < 0 else ""),
        ),
        ("final drill", stop_text),
        (
            "margin budget",
            "not known (no landmark)"
            if budget_mm is None
            else f"{budget_mm:.1f} mm for {placement} placement: the 95th percentile of "
            "placement, canal and CT errors (docs/margin_budget.md)"
            + (
                "; the implant's clearance is under it"
                if facts.nerve_mm is not None and facts.nerve_mm < budget_mm
                else ""
            ),
        ),
        (
            "accuracy",
            f"clearances and walls known to about +-{facts.accuracy_mm:.2g} mm on this CT "
            "(half its coarsest sampling), printed to that",
        ),
    ]


def _final_entry(entries: Sequence[Entry], plan: Plan) -> Entry | None:
    mine = [e for e in entries if e.result.plan.name == plan.name]
    return mine[-1] if mine else None


def drill_rows(facts: ImplantFacts, mine: Sequence[Entry]) -> list[list[str]]:
    """The protocol table: each drill by its diameter, its tip, drilled depth, clearance at
    that depth (two decimals and the CT's accuracy) and verdict against its margin."""
    rows = []
    for k, d in enumerate(facts.drills, start=1):
        entry = mine[k - 1] if len(mine) == len(facts.drills) else None
        clear, verdict = "-", "not computed"
        if entry is not None:
            o = entry.summary.outcome
            c = o.plan_clearance_mm
            margin = o.margin_mm if o.binding_landmark is None else o.binding_landmark.margin_mm
            if c is None:
                verdict = "no landmark"
            else:
                clear = f"{c:.2f} +-{facts.accuracy_mm:.2g}"
                verdict = (
                    f"keeps the {margin:g} mm margin"
                    if c >= margin
                    else f"INSIDE THE {margin:g} mm MARGIN"
                )
        rows.append(
            [
                f"{d.diameter_mm:g} mm",
                f"{d.diameter_mm:g}",
                f"{d.tip_length_mm:g}",
                f"{d.drilled_depth_mm:.2f}",
                f"{d.drilled_depth_mm - facts.apex_depth_mm:.2f}",
                clear,
                verdict,
            ]
        )
    return rows


def signature_block(pages: TextPages) -> None:
    """Planned by, date, approved: lines to sign."""
    pages.gap(0.25)
    pages.paragraph("   ".join(SIGNATURE), size_pt=10.0)


def clinical_pages(pages: TextPages, case: PreparedCase, entries: Sequence[Entry]) -> None:
    """One page per drawn trajectory with an implant (module docstring), its zoomed
    cross-section and panoramic with the distances drawn at its foot."""
    from ctdrill.app.report.implant_view import case_panorama, implant_views

    finals = [e for e in drawn_entries(entries)]
    drawn = {e.result.plan.name for e in finals}
    pano = None
    for plan in case.plans:
        if plan.implant is None or plan.name not in drawn:
            continue
        entry = _final_entry(entries, plan)
        if entry is None:
            continue
        if pano is None:
            pano = case_panorama(case, finals)
        facts = implant_facts(case.volume, plan, entry.result.implant)
        assert facts is not None
        o = entry.summary.outcome
        stop = (
            f"stops at {o.stop_depth_mm:.2f} mm ({stop_words(o.stop_reason, form='plain')}) of "
            f"{o.planned_depth_mm:.2f} mm drilled"
        )
        budget = o.margin_budget
        pages.new_page()
        pages.paragraph(f"Implant: {facts.plan}", size_pt=13.0, bold=True)
        pages.table(
            ITEM_COLUMNS,
            implant_items(
                facts,
                stop,
                None if budget is None else budget.budget_mm,
                "" if budget is None else budget.placement,
                None if entry.result.implant is None else entry.result.implant.tooth_mm,
            ),
            size_pt=8.0,
        )
        pages.gap(0.06)
        mine = [e for e in entries if e.result.plan.name == plan.name]
        pages.table(DRILL_COLUMNS, drill_rows(facts, mine), size_pt=8.0)
        problems = [w for w in entry.summary.warnings if w.code in BANNER]
        for w in dict.fromkeys(problems):
            pages.paragraph(f"[{w.code}] {w.message}", size_pt=7.5, colour="#a01010")
        fig, top, height = pages.remaining_figure(2.0)
        why = implant_views(fig, top, height, case, entry, facts, finals, pano)
        if why is not None:
            fig.text(0.1, 1.0 - (top + 0.3) / 8.27, why, fontsize=9)


def appendix_pages(pages: TextPages, entries: Sequence[Entry]) -> None:
    """The engineering appendix (module docstring): a table and each trajectory's lines."""
    pages.new_page()
    pages.paragraph("Appendix: engineering detail", size_pt=14.0, bold=True)
    pages.gap(0.1)
    rows = []
    for e in entries:
        s = e.summary
        band = s.force_band
        rows.append(
            [
                e.label,
                s.outcome.calibration.name
                + (
                    " - ILLUSTRATIVE, not measured on bone"
                    if s.outcome.calibration.illustrative
                    else ""
                ),
                "-" if s.peak_force_n is None else f"{s.peak_force_n:.2f}",
                "-" if s.mean_force_n is None else f"{s.mean_force_n:.2f}",
                "-"
                if band is None
                else f"{band.peak_mean_force_n:.2f} at {band.peak_depth_mm:.2f} mm; "
                f"68 %: {band.peak_lo_n:.2f}-{band.peak_hi_n:.2f}",
                f"{s.extrapolation.clipped_samples} of {s.extrapolation.samples}",
            ]
        )
    pages.table(APPENDIX_COLUMNS, rows)
    pages.gap(0.15)
    for e in entries:
        o = e.summary.outcome
        pages.paragraph(e.label, size_pt=10.0, bold=True, keep_with_next_in=0.3)
        for line in (
            calibration_line(o.calibration),
            band_line(e.summary.force_band, e.summary.force_band_note),
        ):
            pages.paragraph(line, size_pt=8.5, indent_in=0.15)
        pages.gap(0.1)
