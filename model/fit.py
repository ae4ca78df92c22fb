"""Calibration from recordings (paper sections 2.4-3.2; DESIGN.md "Calibration from recordings").

Each recording, cut at a known CT number and feed, gives ``A0`` (the DC term) and ``|Bk|`` at
``fk = k blades rpm / 60`` (Hann-windowed DFT, :func:`ctdrill.model.spectral.extract_components`).
Eq. 13 is fitted in log10 with the exact ``log10(1 + Ke v)`` by nonlinear least squares:

``log10 A0 = b0 + log10(1 + Ke v) + n log10 C'`` and ``log10 |Bk| = b0k + nk log10 C'``
(``Ke = 0`` for the harmonics, as the paper finds). Standard errors come from the Jacobian at the
solution (``s^2 (J^T J)^-1``) and are reported in % of the value, as Tables 2-3.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ctdrill.hu import AIR_HU
from ctdrill.model.calibration import (
    Calibration,
    CalibrationError,
    Harmonic,
    PowerLaw,
    available_calibrations,
    calibration_from_dict,
    calibration_to_dict,
    load_calibration,
)
from ctdrill.model.calibration_cov import ParameterCovariance
from ctdrill.model.errors import ModelInputError
from ctdrill.model.fit_defaults import DEFAULT_DEPTH_WINDOW_MM
from ctdrill.model.recordings import (
    ManifestEntry,
    Recording,
    RecordingError,
    read_manifest,
    read_recording,
)
from ctdrill.model.spectral import amplitude_spectrum, dominant_frequencies, extract_components

#: A recording's cutting window must span this many periods of the lowest harmonic.
MIN_PERIODS: int = 20
#: Manifest feed and the feed measured from position_mm may differ by this fraction.
FEED_TOLERANCE: float = 0.25


class FitInputError(ModelInputError):
    """The recordings cannot determine the requested parameters."""


@dataclass(frozen=True)
class FitParameter:
    """A fitted value with its standard error (same unit)."""

    value: float
    stderr: float

    @property
    def stderr_pct(self) -> float | None:
        """Standard error in % of ``|value|`` (None when the value is 0)."""
        return None if self.value == 0.0 else 100.0 * self.stderr / abs(self.value)


@dataclass(frozen=True)
class Measurement:
    """What one recording says: DC and harmonic amplitudes at a known HU and feed."""

    source: str
    hu: float
    feed_mm_s: float
    dc_n: float
    amplitudes_n: tuple[float, ...]
    #: The strongest spectral peaks in the window (Hz, strongest first), for checking rpm/blades.
    peaks_hz: tuple[float, ...] = ()


@dataclass(frozen=True, eq=False)
class CalibrationFit:
    """A fitted calibration set with its parameter errors.

    ``parameters`` keys: ``a0.b0``, ``a0.n``, ``a0.ke`` and ``harmonics[i].b0``,
    ``harmonics[i].n`` (``i`` indexes ``calibration.harmonics``). ``rms_log10`` is the RMS
    residual of each law in log10 units (0.01 is 2.3 %).
    """

    calibration: Calibration
    parameters: Mapping[str, FitParameter]
    rms_log10: Mapping[str, float]
    measurements: tuple[Measurement, ...]
    freqs_hz: tuple[float, ...]


def fit_power_law(
    c_prime: np.ndarray,
    feed_mm_s: np.ndarray,
    amplitude_n: np.ndarray,
    *,
    fit_ke: bool,
    ke_per_mm_s: float = 0.0,
    cov_out: list[np.ndarray] | None = None,
) -> tuple[dict[str, FitParameter], float]:
    """Fit ``log10 y = b0 + log10(1 + Ke v) + n log10 C'`` by nonlinear least squares.

    Parameters
    ----------
    c_prime, feed_mm_s, amplitude_n : ndarray, shape (M,)
        ``C' > 0``, feed (mm/s) and the measured amplitude (N, > 0) of each recording.
    fit_ke : bool
        Fit ``Ke`` (bounded to >= 0); otherwise hold it at ``ke_per_mm_s``.
    cov_out : list, optional
        Receives the covariance of ``(b0, n[, ke])`` (``s^2 (J^T J)^-1``).

    Returns
    -------
    params : dict
        ``b0``, ``n`` and ``ke`` (``ke`` with stderr 0 when held).
    rms_log10 : float
        RMS residual in log10 units.
    """
    from scipy.optimize import least_squares  # imported here: 0.7 s, only calibration needs it

    lc = np.log10(c_prime)
    ly = np.log10(amplitude_n)
    v = np.asarray(feed_mm_s, dtype=np.float64)
    n_par = 3 if fit_ke else 2
    if lc.shape[0] <= n_par:
        raise FitInputError(
            f"{lc.shape[0]} recordings cannot fit {n_par} parameters with errors; "
            f"record at least {n_par + 1}"
        )
    # Start from the linearised problem (Eq. 15): log y ~ b0 + n log C' + Ke v / ln 10.
    design = np.column_stack([np.ones_like(lc), lc] + ([v / math.log(10.0)] if fit_ke else []))
    target = ly if fit_ke else ly - np.log10(1.0 + ke_per_mm_s * v)
    start = np.linalg.lstsq(design, target, rcond=None)[0]

    def unpack(p: np.ndarray) -> tuple[float, float, float]:
        return float(p[0]), float(p[1]), float(p[2]) if fit_ke else ke_per_mm_s

    def residual(p: np.ndarray) -> np.ndarray:
        b0, n, ke = unpack(p)
        return np.asarray(b0 + np.log10(1.0 + ke * v) + n * lc - ly)

    def jacobian(p: np.ndarray) -> np.ndarray:
        _, _, ke = unpack(p)
        cols = [np.ones_like(lc), lc]
        if fit_ke:
            cols.append(v / ((1.0 + ke * v) * math.log(10.0)))
        return np.column_stack(cols)

    if fit_ke:
        start[2] = max(start[2], 0.0)
        lower = np.array([-np.inf, -np.inf, 0.0])
    else:
        lower = np.full(2, -np.inf)
    sol = least_squares(residual, start, jac=jacobian, bounds=(lower, np.inf), method="trf")
    r = residual(sol.x)
    dof = lc.shape[0] - n_par
    s2 = float(r @ r) / dof
    jac = jacobian(sol.x)
    try:
        cov = np.linalg.inv(jac.T @ jac) * s2
    except np.linalg.LinAlgError as exc:
        raise FitInputError("the recordings do not determine the fit (singular Jacobian)") from exc
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    b0, n, ke = unpack(sol.x)
    params = {
        "b0": FitParameter(b0, float(se[0])),
        "n": FitParameter(n, float(se[1])),
        "ke": FitParameter(ke, float(se[2]) if fit_ke else 0.0),
    }
    if cov_out is not None:
        cov_out.append(cov)
    return params, float(np.sqrt(np.mean(r**2)))


def measure_recording(
    recording: Recording,
    entry: ManifestEntry,
    freqs_hz: np.ndarray,
    *,
    depth_window_mm: tuple[float, float] = DEFAULT_DEPTH_WINDOW_MM,
) -> Measurement:
    """DC and harmonic amplitudes of one recording over its full-cutting depth window."""
    lo, hi = depth_window_mm
    where = f"recording {recording.path}"
    sel = (recording.position_mm >= lo) & (recording.position_mm <= hi)
    t = recording.time_s[sel]
    x = recording.position_mm[sel]
    f = recording.force_n[sel]
    need_s = MIN_PERIODS / float(np.min(freqs_hz))
    if t.shape[0] < 16 or t[-1] - t[0] < need_s:
        span = 0.0 if t.shape[0] < 2 else t[-1] - t[0]
        raise RecordingError(
            f"{where}, column position_mm: {span:.3g} s between {lo} and {hi} mm; the fit needs "
            f">= {need_s:.3g} s of full cutting there (record deeper or set the depth window)"
        )
    dt = float(np.median(np.diff(t)))
    f_max = float(np.max(freqs_hz))
    if dt > 1.0 / (2.5 * f_max):
        raise RecordingError(
            f"{where}, column time_s: sampled at {1.0 / dt:.4g} Hz, too slow for {f_max:g} Hz; "
            f"record at >= {2.5 * f_max:g} Hz"
        )
    measured_feed = float(np.polyfit(t - t[0], x, 1)[0])
    if abs(measured_feed - entry.feed_mm_s) > FEED_TOLERANCE * entry.feed_mm_s:
        raise RecordingError(
            f"{where}, column position_mm: advances at {measured_feed:.3g} mm/s but the "
            f"manifest says feed_mm_s = {entry.feed_mm_s:g}; fix the manifest row"
        )
    dc, amps = extract_components(t, f, freqs_hz)
    if dc <= 0.0 or np.any(amps <= 0.0):
        raise RecordingError(
            f"{where}, column force_n: no cutting force (DC {dc:.3g} N) in the depth window; "
            "check the recording"
        )
    spectrum = amplitude_spectrum(f - dc, 1.0 / dt)
    peaks = dominant_frequencies(spectrum, count=3, min_hz=0.25 * float(np.min(freqs_hz)))
    return Measurement(
        source=str(recording.path),
        hu=entry.hu,
        feed_mm_s=entry.feed_mm_s,
        dc_n=dc,
        amplitudes_n=tuple(float(a) for a in amps),
        peaks_hz=tuple(round(float(p), 3) for p in peaks),
    )


def nearest_calibration(c_prime_range: tuple[float, float]) -> Calibration | None:
    """The bundled set whose ``c_prime_range`` is nearest in log-midpoint, or None."""
    mid = 0.5 * (math.log10(c_prime_range[0]) + math.log10(c_prime_range[1]))
    best: tuple[float, Calibration] | None = None
    for name in available_calibrations():
        try:
            cal = load_calibration(name)
        except ModelInputError:
            continue
        cmid = 0.5 * (math.log10(cal.c_prime_range[0]) + math.log10(cal.c_prime_range[1]))
        if best is None or abs(cmid - mid) < best[0]:
            best = (abs(cmid - mid), cal)
    return None if best is None else best[1]


def fit_calibration(
    measurements: Sequence[Measurement],
    *,
    orders: Sequence[int],
    freqs_hz: Sequence[float],
    name: str,
    material: str,
    source: str,
    gate_hu: float | None = None,
    gate_width_hu: float | None = None,
    ke_per_mm_s: float | None = None,
) -> CalibrationFit:
    """Fit a calibration set to measurements (one per recording).

    ``ke_per_mm_s`` holds ``Ke`` fixed (needed when all feeds are equal); otherwise it is fitted.
    ``gate_hu`` / ``gate_width_hu`` default to those of the bundled set nearest in ``C'``.
    ``c_prime_range`` is the range of the recordings' ``C'``.
    """
    if not measurements:
        raise FitInputError("no recordings to fit")
    cp = np.array([m.hu for m in measurements], dtype=np.float64) - AIR_HU  # C'
    if np.any(cp <= 0.0):
        bad = measurements[int(np.argmax(cp <= 0.0))]
        raise FitInputError(
            f"recording {bad.source}: hu {bad.hu:g} gives C' = HU + 1000 <= 0; "
            "calibrate on material denser than air"
        )
    if np.unique(cp).shape[0] < 2:
        raise FitInputError(
            "all recordings are at one CT number, so the exponent n cannot be fitted; "
            "record at least two CT numbers"
        )
    feed = np.array([m.feed_mm_s for m in measurements])
    fit_ke = ke_per_mm_s is None
    if fit_ke and np.unique(feed).shape[0] < 2:
        raise FitInputError(
            "all recordings share one feed, so ke cannot be fitted; record at least two "
            "feeds or give ke (--ke)"
        )
    params: dict[str, FitParameter] = {}
    rms: dict[str, float] = {}
    dc = np.array([m.dc_n for m in measurements])
    a0_cov: list[np.ndarray] = []
    a0_fit, rms["a0"] = fit_power_law(
        cp, feed, dc, fit_ke=fit_ke, ke_per_mm_s=ke_per_mm_s or 0.0, cov_out=a0_cov
    )
    params.update({f"a0.{k}": v for k, v in a0_fit.items()})
    harmonics: list[Harmonic] = []
    for i, order in enumerate(orders):
        amp = np.array([m.amplitudes_n[i] for m in measurements])
        h_fit, rms[f"harmonics[{i}]"] = fit_power_law(cp, feed, amp, fit_ke=False)
        params[f"harmonics[{i}].b0"] = h_fit["b0"]
        params[f"harmonics[{i}].n"] = h_fit["n"]
        harmonics.append(Harmonic(order=int(order), b0=h_fit["b0"].value, n=h_fit["n"].value))
    c_range = (float(cp.min()), float(cp.max()))
    if gate_hu is None or gate_width_hu is None:
        near = nearest_calibration(c_range)
        if near is None:
            raise FitInputError("no bundled calibration to take the gate from; give the gate")
        gate_hu = near.gate_hu if gate_hu is None else gate_hu
        gate_width_hu = near.gate_width_hu if gate_width_hu is None else gate_width_hu
        source = f"{source}; gate from {near.name}"
    if gate_width_hu <= 0.0:
        raise FitInputError(f"gate width must be > 0 HU, got {gate_width_hu}")
    calibration = Calibration(
        name=name,
        material=material,
        source=source,
        c_prime_range=c_range,
        gate_hu=float(gate_hu),
        gate_width_hu=float(gate_width_hu),
        a0=PowerLaw(b0=params["a0.b0"].value, n=params["a0.n"].value),
        ke_per_mm_s=params["a0.ke"].value,
        harmonics=tuple(harmonics),
        feed_range_mm_s=(float(feed.min()), float(feed.max())),
        covariance=ParameterCovariance(
            ("a0.b0", "a0.n", "a0.ke")[: a0_cov[0].shape[0]],
            tuple(tuple(float(v) for v in row) for row in (a0_cov[0] + a0_cov[0].T) / 2.0),
        ),
        method=f"fitted to {len(measurements)} force recordings (ctdrill calibrate)",
    )
    return CalibrationFit(
        calibration=calibration,
        parameters=params,
        rms_log10=rms,
        measurements=tuple(measurements),
        freqs_hz=tuple(float(f) for f in freqs_hz),
    )


def calibrate_from_manifest(
    manifest: str | Path,
    *,
    rpm: float,
    blades: int,
    name: str | None = None,
    material: str = "unspecified",
    orders: Sequence[int] = (1, 2),
    gate_hu: float | None = None,
    gate_width_hu: float | None = None,
    ke_per_mm_s: float | None = None,
    depth_window_mm: tuple[float, float] = DEFAULT_DEPTH_WINDOW_MM,
) -> CalibrationFit:
    """Read a manifest and its recordings, measure each, and fit the set (``ctdrill calibrate``)."""
    if isinstance(blades, bool) or int(blades) != blades or blades < 1:
        raise FitInputError(f"--blades must be an integer >= 1, got {blades}")
    if not math.isfinite(rpm) or rpm <= 0.0:
        raise FitInputError(f"--rpm must be a finite number > 0, got {rpm}")
    if not depth_window_mm[0] < depth_window_mm[1]:
        raise FitInputError(f"depth window must be lo < hi mm, got {depth_window_mm}")
    if not orders or len(set(orders)) != len(orders) or min(orders) < 1:
        raise FitInputError(f"harmonic orders must be distinct integers >= 1, got {orders}")
    if ke_per_mm_s is not None and not (math.isfinite(ke_per_mm_s) and ke_per_mm_s >= 0.0):
        raise FitInputError(f"--ke must be a finite number >= 0 per (mm/s), got {ke_per_mm_s}")
    mpath = Path(manifest)
    freqs = np.array([k * int(blades) * rpm / 60.0 for k in orders])
    measurements = [
        measure_recording(read_recording(e.path), e, freqs, depth_window_mm=depth_window_mm)
        for e in read_manifest(mpath)
    ]
    fit = fit_calibration(
        measurements,
        orders=orders,
        freqs_hz=freqs.tolist(),
        name=name or mpath.stem,
        material=material,
        source=(
            f"fitted by ctdrill calibrate from {mpath.name} ({len(measurements)} recordings, "
            f"{int(blades)} blades, {rpm:g} rpm)"
        ),
        gate_hu=gate_hu,
        gate_width_hu=gate_width_hu,
        ke_per_mm_s=ke_per_mm_s,
    )
    try:  # the set must be one load_calibration accepts, or nothing is written
        calibration_from_dict(calibration_to_dict(fit.calibration), source_path=mpath)
    except CalibrationError as exc:
        reason = str(exc).split(": ", 1)[-1]
        raise FitInputError(
            f"manifest {mpath}: the fit gives an unusable calibration set ({reason}); check that "
            "every recording gives force_n in N, position_mm in mm and the manifest feed_mm_s "
            "in mm/s"
        ) from None
    return fit


def fit_document(fit: CalibrationFit) -> dict[str, Any]:
    """The calibration-set JSON document plus ``"fit"`` (value and stderr in % per parameter)."""
    doc = calibration_to_dict(fit.calibration)
    doc["fit"] = {
        key: {"value": p.value, "stderr": p.stderr, "stderr_pct": p.stderr_pct}
        for key, p in fit.parameters.items()
    }
    doc["fit_info"] = {
        "recordings": len(fit.measurements),
        "freqs_hz": list(fit.freqs_hz),
        "rms_residual_log10": dict(fit.rms_log10),
        "measurements": [
            {
                "file": Path(m.source).name,
                "hu": m.hu,
                "feed_mm_s": m.feed_mm_s,
                "a0_n": m.dc_n,
                "amplitudes_n": list(m.amplitudes_n),
                "peaks_hz": list(m.peaks_hz),
            }
            for m in fit.measurements
        ],
    }
    return doc
