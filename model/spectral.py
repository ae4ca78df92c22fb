"""Spectral analysis of force recordings (paper sections 2.4-2.5): Hann-windowed DFT.

Amplitudes are scaled so that a sine of amplitude ``B`` reads ``B`` at its frequency and a
constant ``A0`` reads ``A0`` at 0 Hz: ``|X(f)| * 2 / sum(w)`` (``1 / sum(w)`` at DC), where
``w`` is the Hann window of Eq. 12.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ctdrill.model.errors import ModelInputError


class SpectralInputError(ModelInputError):
    """A signal passed to the spectral analysis is malformed."""


@dataclass(frozen=True, eq=False)
class Spectrum:
    """One-sided amplitude spectrum.

    Attributes
    ----------
    freqs_hz : ndarray, shape (F,)
    amplitude_n : ndarray, shape (F,)
        Amplitude (N): the sine amplitude at ``f > 0``, the mean at ``f = 0``.
    """

    freqs_hz: np.ndarray
    amplitude_n: np.ndarray


@dataclass(frozen=True, eq=False)
class Spectrogram:
    """Amplitude spectra of overlapping Hann-windowed segments.

    Attributes
    ----------
    times_s : ndarray, shape (M,)
        Centre time of each segment.
    freqs_hz : ndarray, shape (F,)
    amplitude_n : ndarray, shape (M, F)
    """

    times_s: np.ndarray
    freqs_hz: np.ndarray
    amplitude_n: np.ndarray


def hann_window(n: int) -> np.ndarray:
    """Eq. 12: ``w(k) = 0.5 - 0.5 cos(2 pi k / (N - 1))``, shape (n,)."""
    if n < 2:
        raise SpectralInputError(f"a Hann window needs >= 2 samples, got {n}")
    k = np.arange(n)
    return np.asarray(0.5 - 0.5 * np.cos(2.0 * np.pi * k / (n - 1)))


def _signal(force_n: ArrayLike, name: str = "force_n") -> np.ndarray:
    x = np.asarray(force_n, dtype=np.float64)
    if x.ndim != 1 or x.shape[0] < 4:
        raise SpectralInputError(f"{name} must be 1-D with >= 4 samples, got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise SpectralInputError(f"{name} contains NaN or inf; drop or repair those samples")
    return x


def _rate(sample_rate_hz: float) -> float:
    fs = float(sample_rate_hz)
    if not np.isfinite(fs) or fs <= 0.0:
        raise SpectralInputError(f"sample_rate_hz must be finite and > 0, got {sample_rate_hz}")
    return fs


def amplitude_spectrum(force_n: ArrayLike, sample_rate_hz: float) -> Spectrum:
    """Hann-windowed one-sided amplitude spectrum of a uniformly sampled signal.

    Parameters
    ----------
    force_n : array_like, shape (N,)
    sample_rate_hz : float

    Returns
    -------
    Spectrum
        ``freqs_hz`` = ``k fs / N`` for ``k = 0..N//2``.
    """
    x = _signal(force_n)
    fs = _rate(sample_rate_hz)
    w = hann_window(x.shape[0])
    spec = np.abs(np.fft.rfft(x * w)) / w.sum()
    spec[1:] *= 2.0
    if x.shape[0] % 2 == 0:
        spec[-1] /= 2.0  # the Nyquist bin has no mirror image
    return Spectrum(freqs_hz=np.fft.rfftfreq(x.shape[0], d=1.0 / fs), amplitude_n=spec)


def spectrogram(
    force_n: ArrayLike, sample_rate_hz: float, *, segment_s: float = 0.5, overlap: float = 0.5
) -> Spectrogram:
    """Amplitude spectra of Hann-windowed segments (the paper's Fig. 5).

    Parameters
    ----------
    force_n : array_like, shape (N,)
    sample_rate_hz : float
    segment_s : float
        Segment length, s (frequency resolution ``1 / segment_s``).
    overlap : float
        Fraction of a segment shared with the next, in [0, 1).
    """
    x = _signal(force_n)
    fs = _rate(sample_rate_hz)
    n_seg = round(segment_s * fs)
    if n_seg < 4 or n_seg > x.shape[0]:
        raise SpectralInputError(
            f"segment_s={segment_s} gives {n_seg} samples; need 4..{x.shape[0]} (signal length)"
        )
    if not 0.0 <= overlap < 1.0:
        raise SpectralInputError(f"overlap must be in [0, 1), got {overlap}")
    hop = max(1, round(n_seg * (1.0 - overlap)))
    starts = np.arange(0, x.shape[0] - n_seg + 1, hop)
    segments = np.lib.stride_tricks.sliding_window_view(x, n_seg)[starts]
    w = hann_window(n_seg)
    amp = np.abs(np.fft.rfft(segments * w, axis=1)) / w.sum()
    amp[:, 1:] *= 2.0
    if n_seg % 2 == 0:
        amp[:, -1] /= 2.0
    return Spectrogram(
        times_s=(starts + 0.5 * (n_seg - 1)) / fs,
        freqs_hz=np.fft.rfftfreq(n_seg, d=1.0 / fs),
        amplitude_n=amp,
    )


def dominant_frequencies(
    spectrum: Spectrum, *, count: int = 2, min_hz: float = 1.0, rel_height: float = 0.05
) -> np.ndarray:
    """The ``count`` strongest spectral peaks above ``min_hz``, strongest first (Hz).

    A peak is a local maximum at least ``rel_height`` times the strongest one; its frequency
    is refined by parabolic interpolation of the log amplitude (exact for a Gaussian peak,
    within a few % of a bin for Hann).
    """
    f = spectrum.freqs_hz
    a = spectrum.amplitude_n
    inner = np.arange(1, a.shape[0] - 1)
    is_peak = (a[inner] > a[inner - 1]) & (a[inner] >= a[inner + 1]) & (f[inner] >= min_hz)
    peaks = inner[is_peak]
    if peaks.shape[0] == 0:
        return np.zeros(0)
    peaks = peaks[a[peaks] >= rel_height * a[peaks].max()]
    peaks = peaks[np.argsort(a[peaks])[::-1]][:count]
    df = f[1] - f[0]
    tiny = np.finfo(np.float64).tiny
    la, lb, lc = (np.log(np.maximum(a[peaks + d], tiny)) for d in (-1, 0, 1))
    denom = la - 2.0 * lb + lc
    shift = np.where(denom < 0.0, 0.5 * (la - lc) / np.where(denom < 0.0, denom, -1.0), 0.0)
    return np.asarray(f[peaks] + np.clip(shift, -0.5, 0.5) * df)


def extract_components(
    time_s: ArrayLike, force_n: ArrayLike, freqs_hz: ArrayLike
) -> tuple[float, np.ndarray]:
    """DC term and the amplitudes at given frequencies, by a Hann-windowed DFT.

    The DFT is evaluated at exactly ``freqs_hz`` (no bin scalloping); the window's sidelobes
    keep a nearby free-running component (15 Hz beside 30 Hz) and the DC out of the estimate
    when the record spans many periods of the frequency spacing.

    Parameters
    ----------
    time_s : array_like, shape (N,)
        Strictly increasing sample times, s.
    force_n : array_like, shape (N,)
    freqs_hz : array_like, shape (K,)
        Frequencies to read, Hz, > 0.

    Returns
    -------
    dc_n : float
        Window-weighted mean (``A0``), N.
    amplitudes_n : ndarray, shape (K,)
        ``|Bk|``, N.
    """
    x = _signal(force_n)
    t = _signal(time_s, "time_s")
    if t.shape != x.shape:
        raise SpectralInputError(f"time_s has {t.shape[0]} samples but force_n {x.shape[0]}")
    if np.any(np.diff(t) <= 0.0):
        raise SpectralInputError("time_s must be strictly increasing")
    f = np.atleast_1d(np.asarray(freqs_hz, dtype=np.float64))
    if f.ndim != 1 or not np.all(np.isfinite(f)) or np.any(f <= 0.0):
        raise SpectralInputError("freqs_hz must be finite and > 0")
    duration = t[-1] - t[0]
    w = 0.5 - 0.5 * np.cos(2.0 * np.pi * (t - t[0]) / duration)
    # Trapezoid weights make the sum a quadrature, so irregular sampling is handled too.
    dt = np.empty_like(t)
    dt[1:-1] = 0.5 * (t[2:] - t[:-2])
    dt[0] = 0.5 * (t[1] - t[0])
    dt[-1] = 0.5 * (t[-1] - t[-2])
    ww = w * dt
    norm = ww.sum()
    dc = float(np.dot(ww, x) / norm)
    phase = np.exp(-2j * np.pi * f[:, None] * (t - t[0])[None, :])
    amps = 2.0 * np.abs(phase @ (ww * x)) / norm
    return dc, np.asarray(amps)
