"""``ctdrill panorama``: files, arrays that match the CT, refusals as one error line."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from ctdrill.app.cli import main
from ctdrill.imaging.dicom.series import load_series
from ctdrill.imaging.plan.load import load_plan_set

ROOT = Path(__file__).resolve().parents[2]
DEMO_CT = ROOT / "assets" / "demo" / "ct"
DEMO_PLAN = ROOT / "assets" / "demo" / "plan.json"
PHILIPS = "dcmqa_ct_Philips_phantom_notilt_5mm"
PHILIPS_PLAN = ROOT / "tests" / "data" / "philips_head_arch.plan.json"
FILES = {"panorama.png", "panorama.npz", "cross_section.png", "cross_section.npz", "reformat.json"}


def _run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def test_demo_writes_arrays_equal_to_the_ct_samples(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    argv = ["panorama", "--dicom", str(DEMO_CT), "--plan", str(DEMO_PLAN), "--out", str(out)]
    code, stdout, err = _run([*argv, "--slab-mm", "0", "--cs-slab-mm", "0"], capsys)
    assert code == 0, err
    assert {p.name for p in out.iterdir()} == FILES
    assert stdout.count("wrote ") == 5
    volume = load_series(DEMO_CT)
    plan = load_plan_set([DEMO_PLAN])[0]
    doc = json.loads((out / "reformat.json").read_text())
    for name in ("panorama", "cross_section"):
        with np.load(out / f"{name}.npz") as z:
            hu, lps = z["hu"], z["lps"]
            assert hu.dtype == np.float64 and lps.shape == (*hu.shape, 3)
            np.testing.assert_allclose(hu, volume.sample(lps, outside_hu=-1000.0), atol=1e-9)
            assert float(z["pixel_mm"]) == pytest.approx(min(volume.spacing_mm))
            assert doc[name]["shape_hw"] == list(hu.shape)
            assert doc[name]["slab_mm"] == 0.0
    # The cross-section is centred on the first trajectory's axis and contains it.
    with np.load(out / "cross_section.npz") as z:
        lps = z["lps"]
        h, w = z["hu"].shape
    mid = 0.5 * (plan.entry_lps + plan.target_lps)
    np.testing.assert_allclose(lps[h // 2, w // 2], mid, atol=1e-9)
    assert plan.arch_lps is not None
    np.testing.assert_allclose(doc["panorama"]["arch_lps"], plan.arch_lps)
    assert doc["panorama"]["column_letters"] == ["R", "L"] or doc["panorama"]["column_letters"] == [
        "L",
        "R",
    ]
    assert doc["cross_section"]["captions"] == []  # canal, implant and drill all drawn


def test_plan_without_arch_is_one_error_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    raw = json.loads(DEMO_PLAN.read_text())
    raw.pop("arch_mm")
    plan = tmp_path / "no_arch.json"
    plan.write_text(json.dumps(raw))
    out = tmp_path / "out"
    code, _, err = _run(
        ["panorama", "--dicom", str(DEMO_CT), "--plan", str(plan), "--out", str(out)], capsys
    )
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("error: ")
    assert str(plan) in err and "arch_mm" in err and "arch" in err
    assert not out.exists()


def test_bad_options_and_foreign_folder_are_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    base = ["panorama", "--dicom", str(DEMO_CT), "--plan", str(DEMO_PLAN)]
    code, _, err = _run([*base, "--out", str(tmp_path / "a"), "--slab-mm", "-1"], capsys)
    assert code == 2 and err.startswith("error: --slab-mm")
    code, _, err = _run([*base, "--out", str(tmp_path / "a"), "--pixel-mm", "nan"], capsys)
    assert code == 2 and err.startswith("error: --pixel-mm")
    foreign = tmp_path / "mine"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("keep")
    code, _, err = _run([*base, "--out", str(foreign)], capsys)
    assert code == 2 and "notes.txt" in err
    assert [p.name for p in foreign.iterdir()] == ["notes.txt"]


def test_real_philips_head(
    tmp_path: Path, shared_data: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    dicom = shared_data / PHILIPS
    argv = ["panorama", "--dicom", str(dicom), "--plan", str(PHILIPS_PLAN), "--out", str(out)]
    code, _, err = _run([*argv, "--cs-slab-mm", "0"], capsys)
    assert code == 0, err
    volume = load_series(dicom)
    doc = json.loads((out / "reformat.json").read_text())
    assert doc["panorama"]["captions"] == [] and doc["cross_section"]["captions"] == []
    with np.load(out / "cross_section.npz") as z:
        np.testing.assert_allclose(z["hu"], volume.sample(z["lps"]), atol=1e-9)
        h, w = z["hu"].shape
        # The drill site is in the maxillary bone (about 700 HU at the trajectory's middle).
        assert z["hu"][h // 2 + 4, w // 2] > 500.0
    with np.load(out / "panorama.npz") as z:
        hu, lps = z["hu"], z["lps"]
    # Rows span the CT's z range (696.2 to 831.2 mm) top down, at the smallest spacing.
    assert lps[0, 0, 2] == pytest.approx(831.21) and lps[-1, 0, 2] >= 696.21 - 1e-9
    assert hu.shape[0] == int((831.21 - 696.21) / volume.spacing_mm[0] + 1e-9) + 1
    assert (hu > 300.0).mean() > 0.05  # facial bones in the picture


def test_real_gantry_tilt_head_with_a_drill_across_a_gap(
    tmp_path: Path, shared_data: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The tilted, unevenly spaced GE head: the images follow CTVolume.sample; a drill whose
    path cannot be computed (it crosses a slice gap) is drawn as its planned axis and the
    caption says why."""
    arch = [[-50, -60], [-35, -80], [-15, -92], [0, -95], [15, -92], [35, -80], [50, -60]]
    plan = tmp_path / "ge.json"
    raw = json.loads(DEMO_PLAN.read_text())
    raw.update(
        entry_mm=[-15.0, -88.0, 50.0],
        target_mm=[-15.0, -88.0, 38.0],
        landmarks=[],
        arch_mm=[[x, y, 40.0] for x, y in arch],
    )
    raw.pop("series_uid_sha256", None)
    plan.write_text(json.dumps(raw))
    dicom = shared_data / "dcmqa_ct_GE_head_gantrytilt_varspacing"
    out = tmp_path / "out"
    argv = ["panorama", "--dicom", str(dicom), "--plan", str(plan), "--out", str(out)]
    code, _, err = _run([*argv, "--slab-mm", "0", "--cs-slab-mm", "0"], capsys)
    assert code == 0, err
    volume = load_series(dicom)
    for name in ("panorama", "cross_section"):
        with np.load(out / f"{name}.npz") as z:
            np.testing.assert_allclose(z["hu"], volume.sample(z["lps"]), atol=1e-9)
    doc = json.loads((out / "reformat.json").read_text())
    said = " ".join(doc["cross_section"]["captions"])
    assert "drill stop not computed" in said and "slice gap" in said
