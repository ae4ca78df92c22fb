"""The force band in the export: profile.csv columns, summary at the peak, --hu-sigma, no band."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest

from ctdrill.model import load_calibration
from tests.app.test_export import DEMO, _run

LIT = load_calibration("bone-literature")


def _export(out: Path, *extra: str) -> tuple[int, str, str]:
    demo = ["--dicom", str(DEMO / "ct"), "--plan", str(DEMO / "plan.json")]
    return _run(["export", *demo, "--out", str(out), *extra])


@pytest.fixture(scope="module")
def literature_export(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("band") / "out"
    code, stdout, err = _export(out, "--calibration", "bone-literature", "--hu-sigma", "30")
    assert (code, err) == (0, "")
    assert "68 % band" in stdout and "--hu-sigma 30 HU" in stdout
    assert "calibration bone-literature: least-squares fit" in stdout
    return out


def test_profile_band_brackets_the_mean_force(literature_export: Path) -> None:
    with (literature_export / "profile.csv").open(encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0])[-3:] == ["mean_force_n", "mean_force_lo_n", "mean_force_hi_n"]
    factor = 1.0 + LIT.ke_per_mm_s * 0.4
    cut = 0
    for r in rows:
        s0, mean = float(r["s0_n"]), float(r["mean_force_n"])
        lo, hi = float(r["mean_force_lo_n"]), float(r["mean_force_hi_n"])
        assert mean == pytest.approx(s0 * factor, abs=2e-5)
        assert lo <= mean <= hi
        if mean > 1.0:
            cut += 1
            # multiplicative band: lo * hi = mean^2
            assert lo * hi == pytest.approx(mean * mean, rel=1e-3)
            assert 0.3 < lo / mean < 0.9
    assert cut > 100


def test_summary_states_the_band_at_the_peak(literature_export: Path) -> None:
    s = json.loads((literature_export / "summary.json").read_text("utf-8"))
    band = s["force_band"]
    assert band["level"] == pytest.approx(0.6827) and band["feed_mm_s"] == 0.4
    assert band["peak_sd_log"] == pytest.approx(
        math.hypot(band["peak_sd_log_calibration"], band["peak_sd_log_hu"]), abs=2e-5
    )
    assert band["peak_lo_n"] < band["peak_mean_force_n"] < band["peak_hi_n"]
    with (literature_export / "profile.csv").open(encoding="utf-8") as fh:
        rows = [r for r in csv.DictReader(fh) if float(r["depth_mm"]) <= s["stop_depth_mm"]]
    peak = max(rows, key=lambda r: float(r["mean_force_n"]))
    assert float(peak["depth_mm"]) == pytest.approx(band["peak_depth_mm"])
    assert float(peak["mean_force_hi_n"]) == pytest.approx(band["peak_hi_n"], abs=1e-4)
    # the demo's cortical plate (about 1700 HU): d ln F / d HU = n / C' for fully cut material
    assert band["peak_sd_log_hu"] == pytest.approx(LIT.a0.n * 30.0 / 2700.0, rel=0.05)
    assert s["hu_uncertainty"]["source"] == "--hu-sigma 30 HU"
    assert s["calibration"] == "bone-literature" and s["calibration_covariance"] is True
    assert "cortical thrust points" in s["calibration_method"]


def test_a_set_without_covariance_gives_no_band_and_says_so(tmp_path: Path) -> None:
    out = tmp_path / "out"
    code, stdout, _ = _export(out, "--hu-sigma", "20")  # the demo's plan: bone-illustrative
    assert code == 0
    s = json.loads((out / "summary.json").read_text("utf-8"))
    assert s["force_band"] is None and s["calibration_covariance"] is False
    assert "gives no parameter covariance" in s["force_band_note"]
    assert "recorded but not used alone" in s["force_band_note"]
    assert s["hu_uncertainty"]["source"] == "--hu-sigma 20 HU"
    assert "no force band: calibration 'bone-illustrative'" in stdout
    with (out / "profile.csv").open(encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    # the mean force needs no covariance: always written; its band columns stay empty
    assert all(float(r["mean_force_n"]) >= 0.0 for r in rows)
    assert any(float(r["mean_force_n"]) > 1.0 for r in rows)
    assert {(r["mean_force_lo_n"], r["mean_force_hi_n"]) for r in rows} == {("", "")}


@pytest.mark.parametrize("bad", ["-1", "nan", "5000"])
def test_bad_hu_sigma_is_exit_2(tmp_path: Path, bad: str) -> None:
    code, _, err = _export(tmp_path / "out", f"--hu-sigma={bad}")
    assert code == 2 and err.startswith("error: --hu-sigma must be a number of HU")
    assert not (tmp_path / "out").exists()


def test_a_plan_without_a_set_gets_bone_literature(tmp_path: Path) -> None:
    plan = json.loads((DEMO / "plan.json").read_text("utf-8"))
    del plan["calibration"]
    path = tmp_path / "plan.json"
    path.write_text(json.dumps(plan), "utf-8")
    out = tmp_path / "out"
    code, _, err = _run(
        ["export", "--dicom", str(DEMO / "ct"), "--plan", str(path), "--out", str(out)]
    )
    assert (code, err) == (0, "")
    s = json.loads((out / "summary.json").read_text("utf-8"))
    assert s["calibration"] == "bone-literature" and s["force_band"] is not None
    assert "HU uncertainty not known, not included" in s["force_band_note"]
    assert s["force_band"]["peak_sd_log_hu"] == 0.0 and s["hu_uncertainty"] is None


def test_rehearsal_summary_states_the_set_and_band(tmp_path: Path) -> None:
    plan = json.loads((DEMO / "plan.json").read_text("utf-8"))
    plan["calibration"] = "bone-literature"
    path = tmp_path / "plan.json"
    path.write_text(json.dumps(plan), "utf-8")
    out = tmp_path / "reh"
    argv = ["rehearse", "--dicom", str(DEMO / "ct"), "--plan", str(path), "--out", str(out)]
    code, stdout, _ = _run(
        [*argv, "--operator", "push:20", "--duration-s", "0.3", "--hu-sigma", "25"]
    )
    assert code == 0
    s = json.loads((out / "summary.json").read_text("utf-8"))
    assert s["calibration"] == "bone-literature" and "literature" in s["calibration_method"]
    assert s["hu_uncertainty"]["source"] == "--hu-sigma 25 HU"
    band = s["force_band"]
    assert band["peak_lo_n"] < band["peak_mean_force_n"] < band["peak_hi_n"]
    assert f"68 % band {band['peak_lo_n']:.2f}-{band['peak_hi_n']:.2f} N" in stdout


def test_the_gui_names_how_each_set_was_obtained() -> None:
    from ctdrill.app.gui.plan_panel import calibration_tooltip

    lit = calibration_tooltip("bone-literature")
    assert (
        lit.startswith("calibration bone-literature: least-squares fit")
        and "68 % force band" in lit
    )
    ill = calibration_tooltip("bone-illustrative")
    assert "(illustrative)" in ill and ill.endswith("(no uncertainty band)")


def test_a_drill_sequence_states_each_drills_band(tmp_path: Path) -> None:
    plan = json.loads((DEMO / "plan.json").read_text("utf-8"))
    drill = plan.pop("drill")
    plan["drills"] = [dict(drill, diameter_mm=2.0), dict(drill, diameter_mm=2.8)]
    plan["calibration"] = "bone-literature"
    path = tmp_path / "plan.json"
    path.write_text(json.dumps(plan), "utf-8")
    out = tmp_path / "out"
    code, stdout, _ = _run(
        ["export", "--dicom", str(DEMO / "ct"), "--plan", str(path), "--out", str(out)]
    )
    assert code == 0
    top = json.loads((out / "summary.json").read_text("utf-8"))
    assert "cortical thrust points" in top["calibration_method"] and top["calibration_covariance"]
    for k, entry in enumerate(top["drills"], start=1):
        own = json.loads((out / f"drill_{k}" / "summary.json").read_text("utf-8"))
        assert entry["force_band"] == own["force_band"] is not None
        assert (
            f"{own['force_band']['peak_lo_n']:.2f}-{own['force_band']['peak_hi_n']:.2f} N" in stdout
        )
    assert "calibration bone-literature: least-squares fit" in stdout


def test_the_gui_force_plot_band_takes_the_hu_sigma(tmp_path: Path) -> None:
    from ctdrill.app.gui.results import compute_path_view
    from ctdrill.engine.grey import hu_sigma_uncertainty
    from ctdrill.imaging import load_series
    from ctdrill.imaging.plan.load import load_plan

    plan = json.loads((DEMO / "plan.json").read_text("utf-8"))
    plan["calibration"] = "bone-literature"
    path = tmp_path / "plan.json"
    path.write_text(json.dumps(plan), "utf-8")
    volume, p = load_series(DEMO / "ct"), load_plan(path)
    bare = compute_path_view(volume, p).curves
    with_hu = compute_path_view(volume, p, hu_sigma_uncertainty(30.0)).curves
    assert bare.mean_hi_n is not None and with_hu.mean_hi_n is not None
    assert np.all(with_hu.mean_hi_n >= bare.mean_hi_n) and np.any(
        with_hu.mean_hi_n > bare.mean_hi_n
    )
    assert bare.band_note.endswith("(calibration)") and with_hu.band_note.endswith("+ HU)")
