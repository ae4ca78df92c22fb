"""``ctdrill calibrate`` end to end: synthetic recordings from known parameters are recovered."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from ctdrill.app.cli import main
from ctdrill.model import load_calibration
from tests.model.synth import TRUE_A0, TRUE_HARMONICS, write_campaign

#: The paper's error bars in % (Table 3 for b0 and n, Table 2 for Ke; A0's b0 takes b'').
BARS_PCT = {
    "a0.b0": 3.75,
    "a0.n": 2.35,
    "a0.ke": 8.5,
    "harmonics[0].b0": 2.68,
    "harmonics[0].n": 2.05,
    "harmonics[1].b0": 7.87,
    "harmonics[1].n": 3.90,
}
TRUTH = {
    "a0.b0": TRUE_A0["b0"],
    "a0.n": TRUE_A0["n"],
    "a0.ke": TRUE_A0["ke"],
    "harmonics[0].b0": TRUE_HARMONICS[0]["b0"],
    "harmonics[0].n": TRUE_HARMONICS[0]["n"],
    "harmonics[1].b0": TRUE_HARMONICS[1]["b0"],
    "harmonics[1].n": TRUE_HARMONICS[1]["n"],
}


@pytest.fixture(scope="module")
def campaign(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_campaign(tmp_path_factory.mktemp("campaign"))


def _calibrate(manifest: Path, out: Path, *extra: str) -> int:
    return main(
        [
            "calibrate",
            str(manifest),
            "--rpm",
            "900",
            "--blades",
            "2",
            "--out",
            str(out),
            "--depth-window-mm",
            "1",
            "3",
            *extra,
        ]
    )


def test_recovers_pine_wood_within_the_papers_error_bars(
    campaign: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "fitted.json"
    assert _calibrate(campaign, out, "--name", "pine-refit", "--material", "pine wood") == 0
    doc = json.loads(out.read_text())
    for key, truth in TRUTH.items():
        value = doc["fit"][key]["value"]
        assert abs(value - truth) <= BARS_PCT[key] / 100 * abs(truth), key
        # The reported error is honest: the truth lies within 4 standard errors.
        assert abs(value - truth) <= 4 * doc["fit"][key]["stderr"] + 1e-12, key
        assert 0.0 < doc["fit"][key]["stderr_pct"] < BARS_PCT[key], key
    cal = load_calibration(out)
    assert cal.name == "pine-refit" and cal.material == "pine wood"
    assert cal.c_prime_range == (200.0, 600.0)  # HU -800..-400
    assert (cal.gate_hu, cal.gate_width_hu) == (-900.0, 50.0)  # nearest bundled: pine wood
    assert [h.order for h in cal.harmonics] == [1, 2]
    # the set carries the DC law's covariance: its diagonal is the reported standard errors
    assert cal.covariance is not None and cal.covariance.parameters == ("a0.b0", "a0.n", "a0.ke")
    for key in cal.covariance.parameters:
        assert cal.covariance.stderr(key) == pytest.approx(doc["fit"][key]["stderr"], rel=1e-9)
    assert cal.method == "fitted to 20 force recordings (ctdrill calibrate)"
    assert doc["fit_info"]["freqs_hz"] == [30.0, 60.0]
    assert doc["fit_info"]["recordings"] == 20
    # The spectra show the drill: 30 and 60 Hz cutting, 15 Hz free-running rotation.
    for m in doc["fit_info"]["measurements"]:
        assert sorted(round(f) for f in m["peaks_hz"]) == [15, 30, 60], m["file"]
    out_text = capsys.readouterr().out
    assert "a0.ke" in out_text and "error (%)" in out_text


def test_fixed_ke_and_explicit_gate(campaign: Path, tmp_path: Path) -> None:
    out = tmp_path / "fixed.json"
    args = ("--ke", "0.25", "--gate-hu", "-850", "--gate-width-hu", "20")
    assert _calibrate(campaign, out, *args) == 0
    doc = json.loads(out.read_text())
    assert doc["a0"]["ke"] == 0.25 and doc["fit"]["a0.ke"]["stderr"] == 0.0
    assert (doc["gate_hu"], doc["gate_width_hu"]) == (-850.0, 20.0)
    assert abs(doc["a0"]["n"] - 0.77) <= 0.0235 * 0.77


def _error_line(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:")
    return lines[0]


def test_missing_column_in_recording_is_exit_2_naming_file_and_column(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "r.csv").write_text("time_s,pos,force_n\n0,0,1\n")
    (tmp_path / "m.csv").write_text("file,hu,feed_mm_s\nr.csv,-600,0.4\n")
    assert _calibrate(tmp_path / "m.csv", tmp_path / "o.json") == 2
    line = _error_line(capsys)
    assert "r.csv" in line and "position_mm" in line


def test_bad_number_in_recording_names_line_and_column(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rows = "\n".join(f"{i / 1000},{i * 1e-4},{'x' if i == 5 else 1.0}" for i in range(40))
    (tmp_path / "r.csv").write_text("time_s,position_mm,force_n\n" + rows + "\n")
    (tmp_path / "m.csv").write_text("file,hu,feed_mm_s\nr.csv,-600,0.4\n")
    assert _calibrate(tmp_path / "m.csv", tmp_path / "o.json") == 2
    line = _error_line(capsys)
    assert "r.csv" in line and "line 7" in line and "force_n" in line


@pytest.mark.parametrize(
    ("manifest", "needle", "names"),
    [
        ("file,hu\nr.csv,-600\n", "feed_mm_s", "m.csv"),
        ("file,hu,feed_mm_s\nr.csv,abc,0.4\n", "line 2, column hu", "m.csv"),
        ("file,hu,feed_mm_s\nr.csv,-600,0\n", "column feed_mm_s", "m.csv"),
        ("file,hu,feed_mm_s\nmissing.csv,-600,0.4\n", "not found", "missing.csv"),
        ("file,hu,feed_mm_s\n", "no recordings", "m.csv"),
    ],
)
def test_bad_manifest_is_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], manifest: str, needle: str, names: str
) -> None:
    (tmp_path / "m.csv").write_text(manifest)
    assert _calibrate(tmp_path / "m.csv", tmp_path / "o.json") == 2
    line = _error_line(capsys)
    assert needle in line and names in line


def test_single_feed_without_ke_says_what_to_do(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    manifest = write_campaign(tmp_path, hus=(-700.0, -500.0), feeds=(0.5,))
    assert _calibrate(manifest, tmp_path / "o.json") == 2
    assert "--ke" in _error_line(capsys)


def test_wrong_feed_in_manifest_is_caught(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    manifest = write_campaign(tmp_path, hus=(-700.0, -500.0), feeds=(0.5,))
    text = manifest.read_text().replace(",0.5\n", ",0.25\n")
    manifest.write_text(text)
    assert _calibrate(manifest, tmp_path / "o.json", "--ke", "0.25") == 2
    line = _error_line(capsys)
    assert "position_mm" in line and "feed_mm_s" in line


def test_literature_fit_through_the_cli_writes_the_committed_set(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from tests.conftest import ASSETS, SHARED

    out = tmp_path / "lit.json"
    code = main(
        [
            "calibrate",
            "--literature",
            str(SHARED / "literature" / "bone_force_points.csv"),
            "--out",
            str(out),
        ]
    )
    stdout = capsys.readouterr().out
    assert code == 0
    assert "points used: MacAvelia2012_human_1000" in stdout and "a0.n" in stdout
    from tests.model.fitcompare import assert_same_fit

    committed = ASSETS / "calibration" / "bone-literature.json"
    assert_same_fit(json.loads(out.read_text("utf-8")), json.loads(committed.read_text("utf-8")))
    load_calibration(out)  # and the written set loads
    # a manifest and --literature together, or a manifest without --rpm: exit 2, says what to do
    assert main(["calibrate", "m.csv", "--literature", "x.csv", "--out", str(out)]) == 2
    assert "not both" in capsys.readouterr().err
    assert main(["calibrate", "m.csv", "--out", str(out)]) == 2
    assert "--rpm and --blades are required" in capsys.readouterr().err
