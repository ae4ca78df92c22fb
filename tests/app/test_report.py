"""``ctdrill report``: a PDF of the planned case whose numbers are the export's.

The PDF is read back with pypdf (an independent reader): it parses, its pages are those the
case asks for, and its text (the summary table, every warning) can be extracted and equals
what ``ctdrill export`` writes into summary.json with the same options.
"""

from __future__ import annotations

import contextlib
import io
import json
import re
from pathlib import Path
from typing import Any

import pypdf
import pytest

from ctdrill.app.cli import main
from tests.conftest import ASSETS

DEMO = ASSETS / "demo"


def run_cli(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as exc:  # argparse usage errors
            code = int(exc.code or 0)
    return code, out.getvalue(), err.getvalue()


def pdf_pages(path: Path) -> list[str]:
    """The text of each page (pypdf), whitespace runs as one space."""
    reader = pypdf.PdfReader(str(path), strict=True)
    return [re.sub(r"\s+", " ", page.extract_text()) for page in reader.pages]


def flat(text: str) -> str:
    return re.sub(r"\s+", "", text)


@pytest.fixture(scope="module")
def demo_report(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The demo's report and its export with the same options (--hu-sigma for a band)."""
    root = tmp_path_factory.mktemp("report")
    common = ["--dicom", str(DEMO / "ct"), "--plan", str(DEMO / "plan.json")]
    options = ["--calibration", "bone-literature", "--hu-sigma", "40"]
    code, out, err = run_cli(
        ["report", *common, *options, "--appendix", "--out", str(root / "r.pdf")]
    )
    assert (code, err) == (0, "")
    assert out == f"wrote {root / 'r.pdf'} (7 pages)\n"
    code, _, err = run_cli(["export", *common, *options, "--out", str(root / "export")])
    assert (code, err) == (0, "")
    return root / "r.pdf", root / "export" / "summary.json"


def test_the_pdf_parses_with_the_pages_of_the_case(demo_report: tuple[Path, Path]) -> None:
    pdf, _ = demo_report
    assert pdf.read_bytes().startswith(b"%PDF-")
    pages = pdf_pages(pdf)
    # summary, the implant's clinical page, panoramic, one cross-section (one trajectory), 3D
    # view, the engineering appendix, one curves page
    assert len(pages) == 7
    assert "Planned osteotomy: summary" in pages[0]
    assert "Implant: plan" in pages[1]
    assert "Panoramic reformat" in pages[2]
    assert "Cross-section: plan" in pages[3]
    assert "3D view" in pages[4]
    assert "Appendix: engineering detail" in pages[5]
    assert "plan: force, HU and clearance against depth" in pages[6]
    for k, text in enumerate(pages, start=1):
        assert f"page {k} of 7" in text


def test_the_implant_page_says_what_a_colleague_needs(demo_report: tuple[Path, Path]) -> None:
    """The demo: a vertical tapered 4.1 x 11.5 implant, its apex 12 mm below the crest, the
    canal's top 12.8 mm below it (centre 14 mm, radius 1.2): 0.8 mm from the implant, inside
    the 2 mm margin; one decimal on 0.4 mm voxels."""
    pdf, summary_json = demo_report
    doc: dict[str, Any] = json.loads(summary_json.read_text(encoding="utf-8"))
    page = pdf_pages(pdf)[1]
    assert "angulation 0.0 deg to the patient's vertical" in page
    assert (
        "0.8 mm from the implant body to 'left mandibular canal' (margin 2 mm): INSIDE THE "
        "SAFETY MARGIN" in page
    )
    walls = doc["bone_walls"]
    assert (
        f"thinnest {walls['min_mm']:.1f} mm; buccal {walls['buccal_mm']:.1f} mm, lingual "
        f"{walls['lingual_mm']:.1f} mm" in page
    )
    assert "12.8 mm (crest at" in page  # bone height from the crest to the canal
    # the drill by its diameter, its tip, drilled depth, beyond the apex, clearance, verdict
    assert "2 mm 2 0.6 12.60 0.60 0.20 +-0.2 INSIDE THE 2 mm MARGIN" in page
    assert "site not given" in page and "tapered 4.1 x 11.5" in page
    assert "[implant_violates_margin]" in page
    # engineering detail is in the appendix, not on the summary page
    appendix = pdf_pages(pdf)[5]
    band = doc["force_band"]
    assert f"{band['peak_mean_force_n']:.2f} at {band['peak_depth_mm']:.2f} mm" in appendix
    assert "calibration bone-literature: " in appendix
    assert "calibration bone-literature: " not in pdf_pages(pdf)[0]


def _table_cells(page: str) -> str:
    """The table row's text: after the headings, before the note under the table."""
    start = page.index("wall (mm)", page.index("thinnest"))
    return page[start : page.index("Depths are the drill tip")]


def test_the_table_holds_the_exports_numbers(demo_report: tuple[Path, Path]) -> None:
    pdf, summary_json = demo_report
    doc: dict[str, Any] = json.loads(summary_json.read_text(encoding="utf-8"))
    row = _table_cells(pdf_pages(pdf)[0])
    # every number as the export's terminal lines print it, from the export's own summary
    for key in ("planned_depth_mm", "stop_depth_mm", "max_safe_depth_mm"):
        assert f"{doc[key]:.3f}" in row, key
    # clearances with the digits 0.4 mm voxels support (+-0.2 mm: one decimal)
    assert doc["clearance_accuracy_mm"] == 0.2
    assert f"{doc['min_clearance_mm']:.1f}" in row
    assert f"{doc['plan_clearance_mm']:.1f}" in row
    binding = doc["binding_landmark"]
    assert binding["name"] in row and f"margin {binding['margin_mm']:g} mm" in row
    assert f"{binding['clearance_at_stop_mm']:.1f} at stop" in row
    assert "(safety margin)" in row and doc["stop_reason"] == "margin"
    assert f"{doc['implant_clearance_mm']:.1f} to left" in row
    assert f"{doc['bone_walls']['min_mm']:.1f}" in row
    # the force band and the calibration: in the appendix's table
    appendix = pdf_pages(pdf)[5]
    band = doc["force_band"]
    assert f"{band['peak_mean_force_n']:.2f} at {band['peak_depth_mm']:.2f} mm" in appendix
    assert f"68 %: {band['peak_lo_n']:.2f}-{band['peak_hi_n']:.2f}" in appendix
    assert doc["calibration"] == "bone-literature" and "bone-literature" in appendix
    assert not doc["calibration_illustrative"] and "ILLUSTRATIVE" not in appendix
    drill = doc["drill"]
    assert f"{drill['diameter_mm']:g} mm, tip {drill['tip_length_mm']:g} mm" in row


def test_every_warning_and_summary_line_is_there_in_full(demo_report: tuple[Path, Path]) -> None:
    from ctdrill.app.summary_lines import summary_lines
    from ctdrill.engine.summary import read_summary

    pdf, summary_json = demo_report
    doc = json.loads(summary_json.read_text(encoding="utf-8"))
    text = flat(" ".join(pdf_pages(pdf)))
    lines = summary_lines(read_summary(doc))
    assert any(line.startswith("warning [plan_violates_margin]") for line in lines)
    assert any(line.startswith("warning [implant_violates_margin]") for line in lines)
    for line in lines:  # wrapped over several lines, never cut
        assert flat(line) in text, line


def test_no_patient_identifier_unless_asked(tmp_path: Path) -> None:
    from ctdrill.engine.case import read_patient_fields
    from ctdrill.imaging import load_series

    uid = load_series(DEMO / "ct").info.series_uid
    phi = read_patient_fields(DEMO / "ct", uid)
    assert phi["patient_name"] and phi["patient_id"]
    common = ["--dicom", str(DEMO / "ct"), "--plan", str(DEMO / "plan.json")]
    code, _, err = run_cli(["report", *common, "--out", str(tmp_path / "a.pdf")])
    assert (code, err) == (0, "")
    raw = (tmp_path / "a.pdf").read_bytes()
    text = " ".join(pdf_pages(tmp_path / "a.pdf"))
    for value in (phi["patient_name"], phi["patient_id"], uid):
        assert value not in text and value.encode() not in raw
    assert "no patient identifiers in this report" in text
    # no date or identifier in the metadata: the same inputs give the same bytes
    code, _, err = run_cli(["report", *common, "--out", str(tmp_path / "again.pdf")])
    assert (code, err) == (0, "") and (tmp_path / "again.pdf").read_bytes() == raw
    code, _, err = run_cli(["report", *common, "--include-phi", "--out", str(tmp_path / "b.pdf")])
    assert (code, err) == (0, "")
    text = " ".join(pdf_pages(tmp_path / "b.pdf"))
    assert phi["patient_name"] in text and phi["patient_id"] in text and uid in text


def test_bad_input_is_one_error_line_and_leaves_the_old_report(tmp_path: Path) -> None:
    out = tmp_path / "r.pdf"
    out.write_bytes(b"previous report")
    bad_plan = tmp_path / "bad.json"
    bad_plan.write_text('{"format": "ctdrill-plan/1", "entry_mm": [0, 0]}', encoding="utf-8")
    ct, plan = str(DEMO / "ct"), str(DEMO / "plan.json")
    cases = [
        ["--dicom", ct, "--plan", str(bad_plan), "--out", str(out)],  # a plan missing fields
        ["--dicom", str(tmp_path / "nothing"), "--plan", plan, "--out", str(out)],  # no CT
        ["--dicom", ct, "--plan", plan, "--out", str(tmp_path)],  # a folder, not a file
        ["--dicom", ct, "--plan", plan, "--out", str(out), "--hu-sigma", "-3"],
    ]
    for argv in cases:
        code, stdout, err = run_cli(["report", *argv])
        assert code == 2, argv
        assert err.startswith("error: ") and err.count("\n") == 1, err
        assert "Traceback" not in err and stdout == ""
        assert out.read_bytes() == b"previous report"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.json", "r.pdf"]


def test_several_trajectories_and_a_drill_sequence_each_get_their_rows_and_pages(
    tmp_path: Path,
) -> None:
    """Two plan files: the demo's, and a second trajectory 6 mm along the canal drilled with a
    2.0 then a 2.8 mm drill. Each drill is a row holding the numbers of its own summary.json
    (``ctdrill export --per-trajectory``); each trajectory has a cross-section, each drill a
    curves page."""
    from dataclasses import replace

    import numpy as np

    from ctdrill.imaging.plan.load import load_plan
    from ctdrill.imaging.plan.types import DrillSpec
    from ctdrill.imaging.plan.write import save_plan

    demo = load_plan(DEMO / "plan.json")
    shift = np.array([0.0, 6.0, 0.0])
    second = replace(
        demo.with_drills((DrillSpec(diameter_mm=2.0, tip_length_mm=0.6), DrillSpec(2.8, 0.84))),
        name="second",
        entry_lps=demo.entry_lps + shift,
        target_lps=demo.target_lps + shift,
    )
    save_plan(second, tmp_path / "second.json")
    common = ["--dicom", str(DEMO / "ct"), "--plan", str(DEMO / "plan.json")]
    common += ["--plan", str(tmp_path / "second.json")]
    code, out, err = run_cli(["report", *common, "--appendix", "--out", str(tmp_path / "r.pdf")])
    assert code == 0 and "Traceback" not in err
    code, _, _ = run_cli(["export", *common, "--per-trajectory", "--out", str(tmp_path / "x")])
    assert code == 0
    pages = pdf_pages(tmp_path / "r.pdf")
    n = len(pages)
    *progress, last = out.splitlines()  # the progress bar on stdout, then the file
    assert last == f"wrote {tmp_path / 'r.pdf'} ({n} pages)"
    assert [line[:8] for line in progress] == ["report [", "report ["] and err == ""
    titles = [p for p in pages if "Cross-section: " in p]
    assert len(titles) == 2
    assert "Cross-section: plan" in titles[0] and "Cross-section: second, drill 2 of 2" in titles[1]
    curves = [p for p in pages if "force, HU and clearance against depth" in p]
    assert len(curves) == 3  # plan; second drill 1; second drill 2
    summary_text = " ".join(p for p in pages if "Panoramic reformat" not in p)
    docs = {
        "plan": json.loads((tmp_path / "x" / "plan" / "summary.json").read_text()),
        "second, drill 1 of 2": json.loads(
            (tmp_path / "x" / "second" / "drill_1" / "summary.json").read_text()
        ),
        "second, drill 2 of 2": json.loads(
            (tmp_path / "x" / "second" / "drill_2" / "summary.json").read_text()
        ),
    }
    first = pages[0]
    for label, doc in docs.items():
        start = first.index(label + " ")
        row = first[start : start + 400]
        assert f"{doc['stop_depth_mm']:.3f}" in row and f"{doc['planned_depth_mm']:.3f}" in row
        assert f"{doc['drill']['diameter_mm']:g} mm" in row
        for w in doc["warnings"]:
            assert flat(w["message"]) in flat(summary_text)
    assert "drill 2 of 2 (final)" in first


def test_a_plan_without_an_arch_gets_its_report_saying_how_to_add_one(tmp_path: Path) -> None:
    from dataclasses import replace

    from ctdrill.imaging.plan.load import load_plan
    from ctdrill.imaging.plan.write import save_plan

    plan = replace(load_plan(DEMO / "plan.json"), arch_lps=None)
    save_plan(plan, tmp_path / "no_arch.json")
    argv = ["report", "--dicom", str(DEMO / "ct"), "--plan", str(tmp_path / "no_arch.json")]
    argv.append("--appendix")
    code, _, err = run_cli([*argv, "--out", str(tmp_path / "r.pdf")])
    assert (code, err) == (0, "")
    pages = pdf_pages(tmp_path / "r.pdf")
    assert len(pages) == 7
    for page in pages[2:4]:  # the panoramic and the cross-section say why, and how
        assert "No dental arch in the plan" in page
        assert "arch_mm" in page and "ctdrill gui" in page and "'arch'" in page
    assert "3D view" in pages[4]
    # without an arch the walls have no buccal or lingual side
    assert "buccal and lingual need a dental arch in the plan" in pages[1]
    assert "Planned osteotomy: summary" in pages[0]


def test_a_reformat_the_plan_cannot_give_is_said_on_its_page(tmp_path: Path) -> None:
    """A horizontal drill along the arch's bucco-lingual normal spans no cross-section plane
    (the reformat refuses it): its page says why; the rest of the report stands."""
    from dataclasses import replace

    import numpy as np

    from ctdrill.imaging.plan.load import load_plan
    from ctdrill.imaging.plan.write import save_plan

    demo = load_plan(DEMO / "plan.json")
    across = replace(
        demo, entry_lps=np.array([18.0, 10.0, -35.0]), target_lps=np.array([30.0, 10.0, -35.0])
    )
    save_plan(across, tmp_path / "across.json")
    argv = ["report", "--dicom", str(DEMO / "ct"), "--plan", str(tmp_path / "across.json")]
    argv.append("--appendix")
    code, _, err = run_cli([*argv, "--out", str(tmp_path / "r.pdf")])
    assert (code, err) == (0, "")
    pages = pdf_pages(tmp_path / "r.pdf")
    assert len(pages) == 7
    assert "Panoramic reformat along the dental arch" in pages[2]
    assert (
        "Not drawn: cross-section: the axis runs along the arch's bucco-lingual normal"
        in (pages[3])
    )
    assert "The rest of the report is unaffected." in pages[3]


def test_the_clinical_summary_of_two_implants_fits_four_pages(tmp_path: Path) -> None:
    """Without --appendix: the case page with the signature block and one page per implant
    with its per-drill clearance and verdict, the margin budget and its zoomed views; no force
    or calibration page."""
    from dataclasses import replace

    import numpy as np

    from ctdrill.imaging.plan.load import load_plan
    from ctdrill.imaging.plan.write import write_plans

    demo = load_plan(DEMO / "plan.json")
    shift = np.array([0.0, 7.0, 0.0])
    second = replace(
        demo, name="second", entry_lps=demo.entry_lps + shift, target_lps=demo.target_lps + shift
    )
    write_plans([replace(demo, name="first", site=36), second], tmp_path / "two.json")
    common = ["--dicom", str(DEMO / "ct"), "--plan", str(tmp_path / "two.json")]
    code, _, err = run_cli(["report", *common, "--out", str(tmp_path / "r.pdf")])
    assert (code, err) == (0, "")
    pages = pdf_pages(tmp_path / "r.pdf")
    assert len(pages) <= 4
    text = " ".join(pages)
    assert "Planned by:" in text and "Approved by:" in text
    assert "Implant: first" in text and "Implant: second" in text
    assert "margin budget" in text and "freehand placement" in text
    assert "INSIDE THE 2 mm MARGIN" in text  # the demo's 2 mm drill, 0.2 mm from the canal
    assert "cross-section (zoomed)" in text and "mm to canal" in text
    assert "Appendix" not in text and "force, HU and clearance" not in text
