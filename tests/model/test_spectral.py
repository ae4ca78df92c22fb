"""Hann-windowed DFT: amplitude scaling, spectrogram, dominant frequencies, component extraction."""

from __future__ import annotations

import numpy as np
import pytest

from ctdrill.model import ModelInputError
from ctdrill.model.spectral import (
    amplitude_spectrum,
    dominant_frequencies,
    extract_components,
    hann_window,
    spectrogram,
)

FS = 1000.0


def test_hann_window_is_eq_12() -> None:
    w = hann_window(5)
    np.testing.assert_allclose(w, [0.0, 0.5, 1.0, 0.5, 0.0], atol=1e-15)


def test_on_bin_sine_reads_its_amplitude_and_dc_reads_a0() -> None:
    t = np.arange(2000) / FS  # 2 s, bins every 0.5 Hz: 30 and 60 Hz are on bins
    x = 4.3 + 0.45 * np.sin(2 * np.pi * 30 * t + 0.7) + 0.09 * np.cos(2 * np.pi * 60 * t)
    s = amplitude_spectrum(x, FS)
    assert s.freqs_hz[60] == 30.0 and s.freqs_hz[120] == 60.0
    assert s.amplitude_n[0] == pytest.approx(4.3, rel=1e-3)
    assert s.amplitude_n[60] == pytest.approx(0.45, rel=1e-3)
    assert s.amplitude_n[120] == pytest.approx(0.09, rel=1e-2)
    # Away from the tones the Hann sidelobes are negligible.
    assert s.amplitude_n[200:].max() < 1e-4


def test_dominant_frequencies_find_30_and_60_hz_over_free_running_15() -> None:
    rng = np.random.default_rng(1)
    t = np.arange(3300) / FS
    x = (
        4.0
        + 0.4 * np.sin(2 * np.pi * 30 * t)
        + 0.08 * np.sin(2 * np.pi * 60 * t)
        + 0.03 * np.sin(2 * np.pi * 15 * t)
        + rng.normal(0, 0.05, t.size)
    )
    f = dominant_frequencies(amplitude_spectrum(x, FS), count=2)
    np.testing.assert_allclose(f, [30.0, 60.0], atol=0.05)
    f3 = dominant_frequencies(amplitude_spectrum(x, FS), count=3, rel_height=0.01)
    np.testing.assert_allclose(f3, [30.0, 60.0, 15.0], atol=0.05)


def test_dominant_frequencies_off_bin_refined() -> None:
    t = np.arange(1000) / FS  # bins every 1 Hz; 33.3 Hz is off-bin
    f = dominant_frequencies(amplitude_spectrum(np.sin(2 * np.pi * 33.3 * t), FS), count=1)
    assert f[0] == pytest.approx(33.3, abs=0.05)


def test_spectrogram_tracks_a_tone_that_starts_midway() -> None:
    t = np.arange(4000) / FS
    x = np.where(t >= 2.0, 0.5 * np.sin(2 * np.pi * 30 * t), 0.0)
    sg = spectrogram(x, FS, segment_s=0.5, overlap=0.5)
    assert sg.amplitude_n.shape == (sg.times_s.shape[0], sg.freqs_hz.shape[0])
    col = int(np.argmin(np.abs(sg.freqs_hz - 30.0)))
    before = sg.times_s < 1.7
    after = sg.times_s > 2.3
    assert np.all(sg.amplitude_n[before, col] < 1e-12)
    np.testing.assert_allclose(sg.amplitude_n[after, col], 0.5, rtol=1e-3)


@pytest.mark.parametrize("duration_s", [1.0, 2.37, 8.0])
def test_extract_components_exact_off_bin_with_free_running_and_noise(duration_s: float) -> None:
    rng = np.random.default_rng(7)
    t = np.arange(0.0, duration_s, 1.0 / FS)
    a0, b1, b2 = 4.3, 0.45, 0.09
    x = (
        a0
        + b1 * np.sin(2 * np.pi * 30 * t + 0.4)
        + b2 * np.sin(2 * np.pi * 60 * t + 2.0)
        + 0.05 * np.sin(2 * np.pi * 15 * t + 1.0)
        + rng.normal(0.0, 0.2, t.size)
    )
    dc, amps = extract_components(t, x, [30.0, 60.0])
    # Noise floor of a Hann DFT: sigma * sqrt(1.5 * 2 / N) per amplitude (~0.02 N at 1 s).
    tol = 3 * 0.2 * np.sqrt(3.0 / t.size)
    assert dc == pytest.approx(a0, abs=tol)
    np.testing.assert_allclose(amps, [b1, b2], atol=tol)


def test_extract_components_noise_free_is_tight_and_handles_jittered_sampling() -> None:
    rng = np.random.default_rng(3)
    t = np.arange(4000) / FS + rng.uniform(-0.2, 0.2, 4000) / FS  # 20 % clock jitter
    x = 2.0 + 0.3 * np.sin(2 * np.pi * 30 * t) + 0.02 * np.sin(2 * np.pi * 15 * t)
    dc, amps = extract_components(t, x, [30.0, 60.0])
    assert dc == pytest.approx(2.0, abs=1e-4)
    np.testing.assert_allclose(amps, [0.3, 0.0], atol=1e-3)


@pytest.mark.parametrize(
    ("t", "x", "f", "match"),
    [
        (np.arange(10.0), np.arange(9.0), [30.0], "samples but force_n"),
        (np.zeros(10), np.ones(10), [30.0], "strictly increasing"),
        (np.arange(10.0), np.full(10, np.nan), [30.0], "NaN"),
        (np.arange(10.0), np.ones(10), [0.0], "freqs_hz"),
        (np.arange(2.0), np.ones(2), [30.0], ">= 4 samples"),
    ],
)
def test_extract_components_bad_input(
    t: np.ndarray, x: np.ndarray, f: list[float], match: str
) -> None:
    with pytest.raises(ModelInputError, match=match):
        extract_components(t, x, f)


def test_spectrogram_bad_segment() -> None:
    with pytest.raises(ModelInputError, match="segment_s"):
        spectrogram(np.ones(100), FS, segment_s=1.0)
    with pytest.raises(ModelInputError, match="sample_rate_hz"):
        amplitude_spectrum(np.ones(100), 0.0)
