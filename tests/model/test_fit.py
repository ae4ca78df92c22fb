"""Fitting Eq. 13: exact recovery on noise-free data, honest errors, and what cannot be fitted."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ctdrill.model import ModelInputError
from ctdrill.model.fit import (
    Measurement,
    fit_calibration,
    fit_document,
    fit_power_law,
    measure_recording,
    nearest_calibration,
)
from ctdrill.model.recordings import ManifestEntry, Recording, read_manifest, read_recording
from tests.model.synth import synth_recording

CP = np.array([200.0, 200.0, 350.0, 350.0, 500.0, 500.0, 650.0])
FEED = np.array([0.1, 0.5, 0.2, 0.4, 0.1, 0.3, 0.5])


def test_noise_free_power_law_recovered_exactly() -> None:
    y = 10**-1.35 * CP**0.77 * (1 + 0.25 * FEED)
    params, rms = fit_power_law(CP, FEED, y, fit_ke=True)
    assert params["b0"].value == pytest.approx(-1.35, abs=1e-8)
    assert params["n"].value == pytest.approx(0.77, abs=1e-8)
    assert params["ke"].value == pytest.approx(0.25, abs=1e-7)
    assert rms < 1e-9
    assert params["n"].stderr < 1e-7


def test_standard_errors_match_the_scatter_they_describe() -> None:
    # 400 repeated fits with 2 % log-normal scatter: the spread of the fitted n equals the
    # reported standard error to within sampling error (about 4 % at 400 repeats).
    rng = np.random.default_rng(11)
    cp = np.repeat(np.array([200.0, 300.0, 450.0, 600.0]), 5)
    feed = np.tile(np.array([0.1, 0.2, 0.3, 0.4, 0.5]), 4)
    truth = 10**-1.35 * cp**0.77 * (1 + 0.25 * feed)
    fitted, reported = [], []
    for _ in range(400):
        y = truth * 10 ** rng.normal(0.0, 0.02 / np.log(10), cp.shape)
        params, _ = fit_power_law(cp, feed, y, fit_ke=True)
        fitted.append(params["n"].value)
        reported.append(params["n"].stderr)
    assert np.std(fitted) == pytest.approx(np.mean(reported), rel=0.15)
    assert np.mean(fitted) == pytest.approx(0.77, abs=3 * np.std(fitted) / 20)


def test_harmonic_law_has_no_ke() -> None:
    y = 10**3.92 * CP**-1.91
    params, _ = fit_power_law(CP, FEED, y, fit_ke=False)
    assert params["ke"].value == 0.0 and params["ke"].stderr == 0.0
    assert params["n"].value == pytest.approx(-1.91, abs=1e-9)
    assert params["b0"].stderr_pct is not None


def _measurements(hus: list[float], feeds: list[float]) -> list[Measurement]:
    out = []
    for hu, v in zip(hus, feeds, strict=True):
        cp = hu + 1000.0
        out.append(
            Measurement(
                source=f"hu{hu}_{v}.csv",
                hu=hu,
                feed_mm_s=v,
                dc_n=10**-1.35 * cp**0.77 * (1 + 0.25 * v),
                amplitudes_n=(10**3.92 * cp**-1.91, 10**1.72 * cp**-1.29),
            )
        )
    return out


def test_fit_calibration_builds_a_loadable_set(tmp_path: Path) -> None:
    ms = _measurements([-800, -700, -600, -500, -400], [0.1, 0.2, 0.3, 0.4, 0.5])
    fit = fit_calibration(
        ms, orders=(1, 2), freqs_hz=(30.0, 60.0), name="t", material="m", source="s"
    )
    cal = fit.calibration
    assert cal.c_prime_range == (200.0, 600.0)
    assert cal.a0.n == pytest.approx(0.77, abs=1e-8)
    assert cal.harmonics[1].b0 == pytest.approx(1.72, abs=1e-8)
    assert "gate from pine-wood-paper" in cal.source
    doc = fit_document(fit)
    assert set(doc["fit"]) == {
        "a0.b0",
        "a0.n",
        "a0.ke",
        "harmonics[0].b0",
        "harmonics[0].n",
        "harmonics[1].b0",
        "harmonics[1].n",
    }


def test_nearest_bundled_set_by_c_prime() -> None:
    near_pine = nearest_calibration((200.0, 600.0))
    near_bone = nearest_calibration((1200.0, 2800.0))
    assert near_pine is not None and near_pine.name == "pine-wood-paper"
    assert near_bone is not None and near_bone.name == "bone-illustrative"


@pytest.mark.parametrize(
    ("hus", "feeds", "match"),
    [
        ([-600, -600, -600, -600], [0.1, 0.2, 0.3, 0.4], "one CT number"),
        ([-700, -600, -500, -400], [0.3, 0.3, 0.3, 0.3], "--ke"),
        ([-700, -600, -500], [0.1, 0.2, 0.3], "at least 4"),
        ([-1000, -600, -500, -400], [0.1, 0.2, 0.3, 0.4], "C'"),
    ],
)
def test_underdetermined_fits_are_refused(hus: list[float], feeds: list[float], match: str) -> None:
    ms = _measurements([max(h, -999.0) for h in hus], feeds)
    if hus[0] == -1000:
        ms[0] = Measurement("air.csv", -1000.0, 0.1, 1.0, (0.1, 0.1))
    with pytest.raises(ModelInputError, match=match):
        fit_calibration(
            ms, orders=(1, 2), freqs_hz=(30.0, 60.0), name="t", material="m", source="s"
        )


def test_measure_recording_window_and_sampling_checks() -> None:
    rng = np.random.default_rng(5)
    t, x, f = synth_recording(-600.0, 0.4, rng, depth_end_mm=3.2)
    rec = Recording(path=Path("r.csv"), time_s=t, position_mm=x, force_n=f)
    entry = ManifestEntry(path=Path("r.csv"), hu=-600.0, feed_mm_s=0.4)
    freqs = np.array([30.0, 60.0])
    m = measure_recording(rec, entry, freqs, depth_window_mm=(1.0, 3.0))
    assert m.dc_n == pytest.approx(10**-1.35 * 400**0.77 * 1.1, rel=0.02)
    with pytest.raises(ModelInputError, match="position_mm"):
        measure_recording(rec, entry, freqs, depth_window_mm=(3.0, 8.0))
    slow = Recording(path=Path("r.csv"), time_s=t[::10], position_mm=x[::10], force_n=f[::10])
    with pytest.raises(ModelInputError, match="too slow for 60 Hz"):
        measure_recording(slow, entry, freqs, depth_window_mm=(1.0, 3.0))


def test_read_recording_and_manifest(tmp_path: Path) -> None:
    rows = "\n".join(f"{i / 1000},{i * 1e-4},2.5,{i}" for i in range(20))
    (tmp_path / "r.csv").write_text("force_n,time_s,position_mm,extra\n" + rows + "\n")
    rec = read_recording(tmp_path / "r.csv")
    # Columns are found by name, not position.
    np.testing.assert_allclose(rec.time_s, np.arange(20) * 1e-4)
    np.testing.assert_allclose(rec.position_mm, np.full(20, 2.5))
    np.testing.assert_allclose(rec.force_n, np.arange(20) / 1000)
    (tmp_path / "m.csv").write_text("feed_mm_s, hu ,file\n0.4,-600,sub/r.csv\n")
    entries = read_manifest(tmp_path / "m.csv")
    assert entries == [ManifestEntry(path=tmp_path / "sub" / "r.csv", hu=-600.0, feed_mm_s=0.4)]


def test_recording_time_must_increase(tmp_path: Path) -> None:
    rows = "\n".join(f"{min(i, 10) / 1000},{i * 1e-4},1.0" for i in range(20))
    (tmp_path / "r.csv").write_text("time_s,position_mm,force_n\n" + rows + "\n")
    with pytest.raises(ModelInputError, match=r"r\.csv, line 13, column time_s"):
        read_recording(tmp_path / "r.csv")


@pytest.mark.parametrize(
    ("content", "match"),
    [
        (b"time_s,position_mm,force_n\n", "only 0 samples"),
        (b"time_s;position_mm;force_n\n0;0;1\n", "separated by commas"),
        (b"\x00\xff\xfe", "cannot read it"),
        (b"", "missing column time_s"),
        (b"time_s,position_mm,force_n\n0,0\n", "line 2, column force_n"),
    ],
)
def test_unusable_recordings_are_named(tmp_path: Path, content: bytes, match: str) -> None:
    path = tmp_path / "rec.csv"
    path.write_bytes(content)
    with pytest.raises(ModelInputError, match=match) as info:
        read_recording(path)
    assert "rec.csv" in str(info.value) and "\n" not in str(info.value)


def test_bom_and_quoted_headers_are_read(tmp_path: Path) -> None:
    rows = "\n".join(f"{i / 1000},{i * 1e-4},1.5" for i in range(20))
    for name, header in (
        ("bom.csv", "\ufefftime_s,position_mm,force_n"),
        ("q.csv", '"time_s","position_mm","force_n"'),
    ):
        (tmp_path / name).write_text(header + "\n" + rows + "\n", encoding="utf-8")
        rec = read_recording(tmp_path / name)
        np.testing.assert_allclose(rec.force_n, 1.5)
    (tmp_path / "m.csv").write_text("\ufefffile,hu,feed_mm_s\nq.csv,-600,0.4\n", encoding="utf-8")
    assert read_manifest(tmp_path / "m.csv")[0].hu == -600.0
