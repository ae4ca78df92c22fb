"""``ctdrill report`` on a real CT: the Philips head series of ``../shared/data`` with two
implants along an arch drawn on its anterior skull (``bench.bench_report.REAL_PLAN``)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from bench.bench_report import REAL_PLAN, real_plan
from tests.app.test_report import flat, pdf_pages, run_cli

PHILIPS = "dcmqa_ct_Philips_phantom_notilt_5mm"


@pytest.fixture(scope="module")
def real_report(
    shared_data: Path, tmp_path_factory: pytest.TempPathFactory
) -> tuple[list[str], Path]:
    root = tmp_path_factory.mktemp("real_report")
    plan = real_plan(root)
    common = ["--dicom", str(shared_data / PHILIPS), "--plan", str(plan)]
    code, out, err = run_cli(["report", *common, "--appendix", "--out", str(root / "r.pdf")])
    assert code == 0 and "Traceback" not in err, err
    code, _, err = run_cli(["report", *common, "--out", str(root / "clinical.pdf")])
    assert code == 0 and "Traceback" not in err, err
    assert out.splitlines()[-1].startswith(f"wrote {root / 'r.pdf'}")  # after the progress
    code, _, err = run_cli(["export", *common, "--per-trajectory", "--out", str(root / "x")])
    assert code == 0, err
    return pdf_pages(root / "r.pdf"), root / "x"


def test_the_clinical_summary_of_two_real_implants_is_at_most_four_pages(
    real_report: tuple[list[str], Path],
) -> None:
    _, export = real_report
    pages = pdf_pages(export.parent / "clinical.pdf")
    assert len(pages) <= 4
    text = " ".join(pages)
    assert "Implant: front" in text and "Implant: left" in text and "Approved by:" in text
    assert "Appendix" not in text


def test_pages_of_two_implants_on_a_real_head(real_report: tuple[list[str], Path]) -> None:
    everything, _ = real_report
    # summary, its warnings continued (the 5 mm slices' coarse_voxels), a clinical page per
    # implant, panoramic, 2 cross-sections, 3D view, the engineering appendix, 3 curves pages
    # (front; left's 2 drills)
    assert len(everything) == 12
    coarse = "warning [coarse_voxels]: coarse voxels: slice step 5 mm"
    assert coarse in everything[0] + everything[1]  # once, the later trajectories refer to it
    for page, name in zip(everything[2:4], ("front", "left"), strict=True):
        assert f"Implant: {name}" in page
        # 5 mm slices: clearances known to +-2.5 mm, printed in whole millimetres
        assert "known to about +-2.5 mm on this CT" in page
    assert "Appendix: engineering detail" in everything[8]
    pages = [everything[0], *everything[4:8], *everything[9:]]
    assert "Panoramic reformat along the dental arch" in pages[1]
    assert "No dental arch" not in " ".join(pages)
    assert "Cross-section: front" in pages[2] and "Cross-section: left, drill 2 of 2" in pages[3]
    assert "3D view" in pages[4]
    names = ["front", "left, drill 1 of 2", "left, drill 2 of 2"]
    for page, name in zip(pages[5:], names, strict=True):
        assert f"{name}: force, HU and clearance against depth" in page
    implant = REAL_PLAN["trajectories"][0]["implant"]  # type: ignore[index]
    assert (
        f"{implant['name']} ({implant['diameter_mm']:g} x {implant['length_mm']:g} mm)" in pages[0]
    )


def test_the_real_heads_table_is_the_exports(real_report: tuple[list[str], Path]) -> None:
    pages, export = real_report
    docs = {
        "front": export / "philips_arch-front" / "summary.json",
        "left, drill 1 of 2": export / "philips_arch-left" / "drill_1" / "summary.json",
        "left, drill 2 of 2": export / "philips_arch-left" / "drill_2" / "summary.json",
    }
    first, text = pages[0], flat(" ".join(pages))
    starts = [first.index(label + " ") for label in docs]
    ends = [*starts[1:], first.index("Depths are the drill tip")]
    for (label, path), start, end in zip(docs.items(), starts, ends, strict=True):
        doc = json.loads(path.read_text(encoding="utf-8"))
        row = first[start:end]
        for key in ("planned_depth_mm", "stop_depth_mm", "max_safe_depth_mm"):
            assert f"{doc[key]:.3f}" in row, (label, key)
        # clearances in whole millimetres: what 5 mm slices support
        assert doc["clearance_accuracy_mm"] == 2.5
        assert f"{doc['min_clearance_mm']:.0f}" in row and f"{doc['plan_clearance_mm']:.0f}" in row
        assert doc["binding_landmark"]["name"] in row
        band = doc["force_band"]
        assert f"{band['peak_lo_n']:.2f}-{band['peak_hi_n']:.2f}" in text  # the appendix
        assert flat(doc["calibration"]) in text
        for w in doc["warnings"]:
            assert flat(w["message"]) in text
