"""Calibration sets: the power-law coefficients of Eq. 13/19-22 for one material.

A set is a JSON file (schema in DESIGN.md section 1)::

    {"name": ..., "material": ..., "source": ...,
     "c_prime_range": [lo, hi], "gate_hu": ..., "gate_width_hu": ...,
     "a0": {"b0": ..., "n": ..., "ke": ...},
     "harmonics": [{"order": 1, "b0": ..., "n": ...}, ...]}

``ke`` is per (mm/s). An optional ``"feed_range_mm_s": [lo, hi]`` gives the feeds the set was
calibrated at (the paper: "the calibration parameters are valid within the ranges used in the
calibration experiments"); a set without it states no feed range (sets written before it stay
valid). An optional ``"fit"`` object (written by ``ctdrill calibrate``) carries the
fit's standard errors and is kept as read, not interpreted. An optional ``"covariance"``
(:mod:`ctdrill.model.calibration_cov`) gives the covariance of the DC law's parameters, from
which outputs draw an uncertainty band; a set without one states no uncertainty. An optional
``"provenance"`` object says how the set was obtained: its ``"method"`` (one sentence) is read
and repeated by every output; the rest (points used, conversions) is kept as read.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ctdrill.model.calibration_cov import ParameterCovariance, parse_covariance
from ctdrill.model.errors import CalibrationError as CalibrationError
from ctdrill.model.errors import ModelInputError
from ctdrill.resources import asset
from ctdrill.safeio import load_json

#: Where named calibration sets live: ``assets/calibration/`` inside the installed package.
CALIBRATION_DIR: Path = asset("calibration")


#: Largest calibration file read, bytes (a set with its fit report is a few kB).
MAX_CALIBRATION_BYTES: int = 4 * 1024 * 1024
#: Largest force (N) a power law may give within its range; more is a unit or sign error.
MAX_LAW_N: float = 1.0e6
#: Smallest force (N) a law must reach somewhere in its range: below it the set cuts nothing.
MIN_LAW_N: float = 1.0e-6
#: Largest |exponent| n of a power law in C' (the fitted sets have |n| < 3).
MAX_EXPONENT: float = 50.0
#: Highest harmonic order accepted (the paper uses 1 and 2; 90 Hz was already noise).
MAX_ORDER: int = 64
#: Largest feed sensitivity accepted, per (mm/s) (the paper's pine wood: 0.25).
MAX_KE_PER_MM_S: float = 1.0e3


@dataclass(frozen=True)
class PowerLaw:
    """``10**b0 * C'**n`` (N), with ``C' = HU + 1000``."""

    b0: float
    n: float


@dataclass(frozen=True)
class Harmonic:
    """Amplitude ``10**b0 * C'**n`` (N) of the harmonic at ``order * blades * rpm / 60`` Hz."""

    order: int
    b0: float
    n: float


@dataclass(frozen=True)
class Calibration:
    """One material's force-law coefficients (DESIGN.md section 1).

    Attributes
    ----------
    name, material, source : str
        Identification; ``source`` says where the numbers come from.
    c_prime_range : tuple of float
        ``(lo, hi)`` of ``C' = HU + 1000`` over which the power laws are valid; every law is
        evaluated at ``C'`` clipped to it. ``0 < lo < hi``.
    gate_hu, gate_width_hu : float
        Centre and width (HU) of the ramp below which nothing is cut.
    a0 : PowerLaw
        DC term at zero feed, N.
    ke_per_mm_s : float
        Feed sensitivity ``Ke`` of ``A0 (1 + Ke v)``, per (mm/s), ``>= 0``.
    harmonics : tuple of Harmonic
        Vibration terms, orders distinct and ascending.
    feed_range_mm_s : tuple of float or None
        ``(lo, hi)`` feeds the set was calibrated at, mm/s (``0 <= lo <= hi``); None when the
        set does not say.
    covariance : ParameterCovariance or None
        Covariance of the DC law's parameters (``a0.b0``, ``a0.n``, ``a0.ke``); None when the
        set gives none (then no output shows a band).
    method : str or None
        How the set was obtained, one sentence (``provenance.method``); None when not said.
    """

    name: str
    material: str
    source: str
    c_prime_range: tuple[float, float]
    gate_hu: float
    gate_width_hu: float
    a0: PowerLaw
    ke_per_mm_s: float
    harmonics: tuple[Harmonic, ...]
    feed_range_mm_s: tuple[float, float] | None = None
    covariance: ParameterCovariance | None = None
    method: str | None = None

    @property
    def illustrative(self) -> bool:
        """True when the set is not a measured calibration (its name or source says so)."""
        return "illustrative" in self.name.lower() or "illustrative" in self.source.lower()


def available_calibrations() -> tuple[str, ...]:
    """Names of the bundled sets in :data:`CALIBRATION_DIR`, sorted."""
    if not CALIBRATION_DIR.is_dir():
        return ()
    return tuple(sorted(p.stem for p in CALIBRATION_DIR.glob("*.json")))


def resolve_calibration_path(name_or_path: str | Path) -> Path:
    """Path of a set given by bundled name (``"pine-wood-paper"``) or by file path."""
    text = str(name_or_path)
    if not text.strip():
        raise CalibrationError(
            "calibration: empty name; give a set name "
            f"({', '.join(available_calibrations())}) or a path to a .json file"
        )
    as_path = Path(text)
    looks_like_path = as_path.suffix.lower() == ".json" or len(as_path.parts) > 1
    if looks_like_path:
        if not as_path.exists():
            raise CalibrationError(f"calibration file {as_path}: not found; check the path")
        return as_path  # load_calibration refuses folders, FIFOs and devices by name
    named = CALIBRATION_DIR / f"{text}.json"
    if named.is_file():
        return named
    if as_path.is_file():
        return as_path
    raise CalibrationError(
        f"calibration {text!r}: no such set in {CALIBRATION_DIR}; "
        f"use one of {', '.join(available_calibrations()) or '(none)'} or a path to a .json file"
    )


def _short(value: Any, limit: int = 40) -> str:
    """``repr`` of a JSON value for an error message, cut to ``limit`` characters."""
    try:
        text = repr(value)
    except ValueError:  # an int beyond Python's digit limit
        text = f"<{type(value).__name__} too large to print>"
    text = " ".join(text.split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _number(obj: Mapping[str, Any], key: str, where: str, src: Path) -> float:
    if key not in obj:
        raise CalibrationError(f"calibration file {src}: missing field {where}{key}; add it")
    value = obj[key]
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise CalibrationError(
            f"calibration file {src}: field {where}{key} must be a number, got {_short(value)}"
        )
    try:
        out = float(value)
    except OverflowError:
        out = math.inf
    if not math.isfinite(out):
        raise CalibrationError(f"calibration file {src}: field {where}{key} must be finite")
    return out


def _text(obj: Mapping[str, Any], key: str, src: Path, default: str | None = None) -> str:
    value = obj.get(key, default)
    if not isinstance(value, str) or not value.strip():
        raise CalibrationError(
            f"calibration file {src}: field {key} must be a non-empty string; set it"
        )
    if any("\ud800" <= c <= "\udfff" for c in value):
        raise CalibrationError(
            f"calibration file {src}: field {key} holds a lone surrogate escape (\\ud800-"
            "\\udfff), which is not text; fix the string"
        )
    return value


def calibration_from_dict(data: Any, *, source_path: Path | str = "<dict>") -> Calibration:
    """Validate a parsed calibration document and return the :class:`Calibration`.

    Raises
    ------
    CalibrationError
        Naming the file and the field at fault.
    """
    src = Path(source_path)
    if not isinstance(data, Mapping):
        raise CalibrationError(f"calibration file {src}: top level must be a JSON object")
    name = _text(data, "name", src, default=src.stem)
    material = _text(data, "material", src)
    source = _text(data, "source", src)

    rng = data.get("c_prime_range")
    if not isinstance(rng, list | tuple) or len(rng) != 2:
        raise CalibrationError(
            f"calibration file {src}: field c_prime_range must be [lo, hi] with 0 < lo < hi"
        )
    lo = _number({"c_prime_range[0]": rng[0]}, "c_prime_range[0]", "", src)
    hi = _number({"c_prime_range[1]": rng[1]}, "c_prime_range[1]", "", src)
    if not 0.0 < lo < hi:
        raise CalibrationError(
            f"calibration file {src}: field c_prime_range must satisfy 0 < lo < hi, "
            f"got [{lo}, {hi}] (C' = HU + 1000 must stay positive)"
        )
    gate_hu = _number(data, "gate_hu", "", src)
    gate_width_hu = _number(data, "gate_width_hu", "", src)
    if gate_width_hu <= 0.0:
        raise CalibrationError(
            f"calibration file {src}: field gate_width_hu must be > 0 HU, got {gate_width_hu}"
        )

    a0 = data.get("a0")
    if not isinstance(a0, Mapping):
        raise CalibrationError(
            f"calibration file {src}: field a0 must be an object {{b0, n, ke}}; add it"
        )
    a0_law = PowerLaw(b0=_number(a0, "b0", "a0.", src), n=_number(a0, "n", "a0.", src))
    ke = _number(a0, "ke", "a0.", src)
    if not 0.0 <= ke <= MAX_KE_PER_MM_S:
        raise CalibrationError(
            f"calibration file {src}: field a0.ke must be in [0, {MAX_KE_PER_MM_S:g}] "
            f"per (mm/s), got {ke}"
        )

    raw_harmonics = data.get("harmonics", [])
    if not isinstance(raw_harmonics, list):
        raise CalibrationError(f"calibration file {src}: field harmonics must be a list")
    harmonics: list[Harmonic] = []
    for i, h in enumerate(raw_harmonics):
        where = f"harmonics[{i}]."
        if not isinstance(h, Mapping):
            raise CalibrationError(
                f"calibration file {src}: field harmonics[{i}] must be an object {{order, b0, n}}"
            )
        order = h.get("order")
        if isinstance(order, bool) or not isinstance(order, int) or not 1 <= order <= MAX_ORDER:
            raise CalibrationError(
                f"calibration file {src}: field {where}order must be an integer in "
                f"[1, {MAX_ORDER}], got {_short(order)}"
            )
        harmonics.append(
            Harmonic(order=order, b0=_number(h, "b0", where, src), n=_number(h, "n", where, src))
        )
    orders = [h.order for h in harmonics]
    if len(set(orders)) != len(orders):
        raise CalibrationError(
            f"calibration file {src}: field harmonics has repeated orders {orders}; "
            "give each order once"
        )
    laws = [("a0", a0_law.b0, a0_law.n)] + [
        (f"harmonics[{i}]", h.b0, h.n) for i, h in enumerate(harmonics)
    ]
    for where, b0, n in laws:
        if abs(n) > MAX_EXPONENT:
            raise CalibrationError(
                f"calibration file {src}: field {where}.n must be within "
                f"[-{MAX_EXPONENT:g}, {MAX_EXPONENT:g}], got {n:g}; check the fit"
            )
        log10_ends = [b0 + n * math.log10(c) for c in (lo, hi)]
        if max(log10_ends) < math.log10(MIN_LAW_N):
            raise CalibrationError(
                f"calibration file {src}: field {where} gives less than {MIN_LAW_N:g} N "
                f"everywhere in c_prime_range [{lo:g}, {hi:g}] (a material cut with no force); "
                "check the sign of b0 and n, or leave the harmonic out"
            )
        if max(log10_ends) > math.log10(MAX_LAW_N):
            raise CalibrationError(
                f"calibration file {src}: field {where} gives more than {MAX_LAW_N:g} N within "
                f"c_prime_range [{lo:g}, {hi:g}]; check the sign and units of b0 and n"
            )
    return Calibration(
        name=name,
        material=material,
        source=source,
        c_prime_range=(lo, hi),
        gate_hu=gate_hu,
        gate_width_hu=gate_width_hu,
        a0=a0_law,
        ke_per_mm_s=ke,
        harmonics=tuple(sorted(harmonics, key=lambda h: h.order)),
        feed_range_mm_s=_feed_range(data, src),
        covariance=parse_covariance(data, src),
        method=_method(data, src),
    )


def _method(data: Mapping[str, Any], src: Path) -> str | None:
    """``provenance.method``: how the set was obtained (None when the set has no provenance)."""
    if "provenance" not in data:
        return None
    prov = data["provenance"]
    if not isinstance(prov, Mapping):
        raise CalibrationError(
            f"calibration file {src}: field provenance must be an object (or leave it out)"
        )
    if "method" not in prov:
        return None
    try:
        return _text(prov, "method", src)
    except CalibrationError:
        raise CalibrationError(
            f"calibration file {src}: field provenance.method must be a non-empty string"
        ) from None


def _feed_range(data: Mapping[str, Any], src: Path) -> tuple[float, float] | None:
    """The optional ``feed_range_mm_s`` [lo, hi] with ``0 <= lo <= hi``, mm/s."""
    if "feed_range_mm_s" not in data:
        return None
    rng = data["feed_range_mm_s"]
    if not isinstance(rng, list | tuple) or len(rng) != 2:
        raise CalibrationError(
            f"calibration file {src}: field feed_range_mm_s must be [lo, hi] in mm/s "
            "with 0 <= lo <= hi (or leave it out)"
        )
    lo = _number({"feed_range_mm_s[0]": rng[0]}, "feed_range_mm_s[0]", "", src)
    hi = _number({"feed_range_mm_s[1]": rng[1]}, "feed_range_mm_s[1]", "", src)
    if not 0.0 <= lo <= hi:
        raise CalibrationError(
            f"calibration file {src}: field feed_range_mm_s must satisfy 0 <= lo <= hi mm/s, "
            f"got [{lo}, {hi}]"
        )
    return (lo, hi)


def load_calibration(name_or_path: str | Path) -> Calibration:
    """Load a calibration set by bundled name or by path.

    Parameters
    ----------
    name_or_path : str or Path
        A name in ``assets/calibration/`` (``"pine-wood-paper"``, ``"bone-illustrative"``) or a
        path to a ``.json`` file.

    Raises
    ------
    CalibrationError
        The set is missing, not JSON, or a field is invalid (the message names file and field).
    """
    path = resolve_calibration_path(name_or_path)
    # a regular file of bounded size, nesting and integer digits (FIFOs, /dev/zero, JSON
    # bombs are refused before they can hang or exhaust memory)
    data = load_json(
        path,
        what="calibration file",
        error=CalibrationError,
        max_bytes=MAX_CALIBRATION_BYTES,
    )
    return calibration_from_dict(data, source_path=path)


def calibration_to_dict(calibration: Calibration) -> dict[str, Any]:
    """The JSON document of a set (inverse of :func:`calibration_from_dict`)."""
    doc: dict[str, Any] = {
        "name": calibration.name,
        "material": calibration.material,
        "source": calibration.source,
        "c_prime_range": [calibration.c_prime_range[0], calibration.c_prime_range[1]],
        "gate_hu": calibration.gate_hu,
        "gate_width_hu": calibration.gate_width_hu,
        "a0": {
            "b0": calibration.a0.b0,
            "n": calibration.a0.n,
            "ke": calibration.ke_per_mm_s,
        },
        "harmonics": [{"order": h.order, "b0": h.b0, "n": h.n} for h in calibration.harmonics],
    }
    if calibration.feed_range_mm_s is not None:
        doc["feed_range_mm_s"] = list(calibration.feed_range_mm_s)
    if calibration.covariance is not None:
        doc["covariance"] = calibration.covariance.to_json()
    if calibration.method is not None:
        doc["provenance"] = {"method": calibration.method}
    return doc


def harmonic_freqs_hz(calibration: Calibration, *, blades: int, rpm: float) -> np.ndarray:
    """Frequencies of the harmonics, ``order * blades * rpm / 60`` (Hz), shape (K,).

    The paper's drill (2 blades, 900 rpm) gives 30 and 60 Hz.
    """
    if isinstance(blades, bool) or not isinstance(blades, int | np.integer) or blades < 1:
        raise ModelInputError(f"drill.blades must be an integer >= 1, got {blades!r}")
    rpm_f = float(rpm)
    if not math.isfinite(rpm_f) or rpm_f <= 0.0:
        raise ModelInputError(f"drill.rpm must be a finite number > 0, got {rpm!r}")
    orders = np.array([h.order for h in calibration.harmonics], dtype=np.float64)
    return orders * (int(blades) * rpm_f / 60.0)
