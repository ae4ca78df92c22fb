"""CBCT grey values -> HU: the map from regions or numbers, applied at load, recorded, its
uncertainty carried into the force band."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest

from ctdrill.imaging import load_series
from ctdrill.imaging.dicom.grey import given_grey_map, grey_map_from_regions, sphere_region
from ctdrill.imaging.phantom.writer import write_series
from tests.app.test_export import DEMO, _run

AIR = ((15.0, -9.0, -55.0), 2.0)
BONE = ((37.0, 10.6, -40.2), 0.8)


@pytest.fixture(scope="module")
def cbct(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The demo CT stored as grey values 2 (HU + 1000) + 30 without a rescale (CBCT-like)."""
    v = load_series(DEMO / "ct")
    grey = (2 * (v.hu.astype(np.int32) + 1000) + 30).astype(np.int16)
    out = tmp_path_factory.mktemp("cbct") / "ct"
    write_series(
        out,
        grey,
        v.affine_lps,
        positions_lps=v.slice_origins_lps,
        valid=v.valid,
        write_rescale=False,
    )
    return out


def _profile(path: Path) -> list[dict[str, str]]:
    with path.open(encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def test_grey_series_is_refused_without_a_map(cbct: Path, tmp_path: Path) -> None:
    demo = ["--plan", str(DEMO / "plan.json"), "--out", str(tmp_path / "o")]
    code, _, err = _run(["export", "--dicom", str(cbct), *demo])
    assert code == 2 and "error:" in err


def test_regions_recover_the_map_and_the_hu_export(cbct: Path, tmp_path: Path) -> None:
    hu_volume = load_series(DEMO / "ct")
    # the true mean HU of each region (same voxels): the fitted map must be HU = grey / 2 - 1015
    known = [sphere_region(hu_volume, c, r, 0.0).mean_grey for c, r in (AIR, BONE)]
    refs = [
        f"{','.join(map(str, c))},{r}={h!r}" for (c, r), h in zip((AIR, BONE), known, strict=True)
    ]
    out = tmp_path / "grey"
    plan = ["--plan", str(DEMO / "plan.json"), "--calibration", "bone-literature"]
    code, stdout, err = _run(
        ["export", "--dicom", str(cbct), *plan, "--out", str(out)]
        + [a for ref in refs for a in ("--grey-ref", ref)]
    )
    assert (code, err) == (0, "")
    s = json.loads((out / "summary.json").read_text("utf-8"))
    g = s["grey_to_hu"]
    assert g["slope"] == pytest.approx(0.5, rel=1e-9)
    assert g["intercept"] == pytest.approx(-1015.0, abs=1e-6)
    assert [r["known_hu"] for r in g["regions"]] == pytest.approx(known)
    assert "not_hu" not in [w["code"] for w in s["warnings"]]
    assert "grey_map_on_hu" not in [w["code"] for w in s["warnings"]]  # grey values: as meant
    assert "grey-to-HU map: HU = 0.5 x grey + -1015" in stdout
    # its uncertainty (from the regions' grey SDs) enters the band
    assert s["hu_uncertainty"]["source"] == "grey-to-HU map"
    assert s["force_band"]["peak_sd_log_hu"] > 0.0
    # the forces are those of the HU series
    ref = tmp_path / "hu"
    assert _run(["export", "--dicom", str(DEMO / "ct"), *plan, "--out", str(ref)])[0] == 0
    for a, b in zip(_profile(out / "profile.csv"), _profile(ref / "profile.csv"), strict=True):
        assert float(a["hu"]) == pytest.approx(float(b["hu"]), abs=0.011)
        assert float(a["s0_n"]) == pytest.approx(float(b["s0_n"]), abs=2e-5)


def test_given_map_with_standard_errors_in_closed_form(cbct: Path, tmp_path: Path) -> None:
    out = tmp_path / "o"
    plan = ["--plan", str(DEMO / "plan.json"), "--calibration", "bone-literature"]
    code, _, err = _run(
        ["export", "--dicom", str(cbct), *plan, "--out", str(out), "--grey-to-hu=0.5,-1015,1e-3,5"]
    )
    assert (code, err) == (0, "")
    s = json.loads((out / "summary.json").read_text("utf-8"))
    assert (s["grey_to_hu"]["slope_se"], s["grey_to_hu"]["intercept_se"]) == (1e-3, 5.0)
    # dHU = grey ds + dc, grey = (HU + 1015) / 0.5: SD at HU h is sqrt(25 + (2 (h + 1015))^2 1e-6)
    unc = s["hu_uncertainty"]
    assert unc["sd_hu_at_0_hu"] == pytest.approx(math.sqrt(25 + (2 * 1015) ** 2 * 1e-6), abs=1e-3)
    assert unc["sd_hu_at_1000_hu"] == pytest.approx(
        math.sqrt(25 + (2 * 2015) ** 2 * 1e-6), abs=1e-3
    )
    # without standard errors: the map is applied and recorded, its uncertainty not known
    out2 = tmp_path / "o2"
    assert (
        _run(["export", "--dicom", str(cbct), *plan, "--out", str(out2), "--grey-to-hu=0.5,-1015"])[
            0
        ]
        == 0
    )
    s2 = json.loads((out2 / "summary.json").read_text("utf-8"))
    assert (
        s2["grey_to_hu"]["slope_se"] is None
        and "uncertainty not known" in s2["grey_to_hu"]["method"]
    )
    assert s2["hu_uncertainty"] is None


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--grey-to-hu", "1,2,3"], "give 2 or 4 comma-separated numbers"),
        (["--grey-ref", "0,0,0,1=-1000"], "at least two regions"),
        (["--grey-ref", "0,0,0=-1000", "--grey-ref", "0,0,0,1=0"], "give 4 comma-separated"),
        (["--grey-to-hu", "1,0", "--grey-ref", "0,0,0,1=0"], "not both"),
        (["--grey-ref", "900,0,0,1=-1000", "--grey-ref", "0,0,0,1=0"], "outside the volume"),
    ],
)
def test_bad_map_options_are_exit_2(
    cbct: Path, tmp_path: Path, args: list[str], message: str
) -> None:
    code, _, err = _run(
        [
            "export",
            "--dicom",
            str(cbct),
            "--plan",
            str(DEMO / "plan.json"),
            "--out",
            str(tmp_path / "o"),
            *args,
        ]
    )
    assert code == 2 and message in err and err.startswith("error:")


def test_two_regions_error_propagation_by_hand() -> None:
    from ctdrill.imaging.dicom.grey import GreyRegion

    a = GreyRegion((0, 0, 0), 1.0, -1000.0, 100.0, 4.0, 50)
    b = GreyRegion((0, 0, 0), 1.0, 1000.0, 1100.0, 6.0, 50)
    m = grey_map_from_regions([a, b])
    assert (m.slope, m.intercept) == pytest.approx((2.0, -1200.0))
    # s = (H2 - H1) / (g2 - g1): ds/dg1 = s / dg, ds/dg2 = -s / dg; c = H1 - s g1
    dg = 1000.0
    var_s = (2.0 / dg) ** 2 * (16 + 36)
    var_c = (-2.0 - 100 * 2.0 / dg) ** 2 * 16 + (100 * 2.0 / dg) ** 2 * 36  # dc/dg1, dc/dg2
    assert m.cov is not None
    assert m.cov[0][0] == pytest.approx(var_s, rel=1e-6)
    assert m.cov[1][1] == pytest.approx(var_c, rel=1e-6)
    assert given_grey_map(2.0, -1200.0).cov is None


def test_rehearsal_applies_and_records_the_map(cbct: Path, tmp_path: Path) -> None:
    plan = json.loads((DEMO / "plan.json").read_text("utf-8"))
    plan["calibration"] = "bone-literature"
    path = tmp_path / "plan.json"
    path.write_text(json.dumps(plan), "utf-8")
    out = tmp_path / "reh"
    argv = ["rehearse", "--dicom", str(cbct), "--plan", str(path), "--out", str(out)]
    code, stdout, _ = _run(
        [*argv, "--operator", "push:20", "--duration-s", "0.3", "--grey-to-hu=0.5,-1015,1e-3,5"]
    )
    assert code == 0
    s = json.loads((out / "summary.json").read_text("utf-8"))
    assert s["grey_to_hu"]["slope"] == 0.5 and s["hu_uncertainty"]["source"] == "grey-to-HU map"
    assert "grey-to-HU map: HU = 0.5 x grey + -1015 (SE 0.001, 5)" in stdout
