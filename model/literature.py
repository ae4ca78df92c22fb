"""The ``bone-literature`` calibration set, fitted to published bone-drilling points.

Data: ``bone_force_points.csv`` (one row per published point; its README says what the points
support). No study gives thrust against CT number, so the DC law
``A0 = 10^b0 C'^n (1 + Ke v)`` is fitted jointly to two groups, in log10:

- **density exponent n**: drilling torque at four Misch classes in bovine rib (D2-D5;
  :data:`TORQUE_KEYS`), ``log10 T = a_T + n log10 C'``, with a nuisance level ``a_T`` (torque is
  not thrust; only the slope is shared: both are assumed proportional to the material's specific
  cutting pressure). Each class gets its midpoint HU (:func:`class_hu_ranges` of the Misch
  bands the caller passes, an assignment the study does not report) and the class width enters
  as an HU error ``width / sqrt(12)`` through the slope (effective variance), beside the
  standard error of the mean torque (SD / sqrt(sites)).
- **level b0 and feed sensitivity Ke**: the cortical thrust points whose drill diameter, feed and
  speed are all stated (:data:`THRUST_KEYS`), each converted to the reference drill
  (:data:`REF_DIAMETER_MM`, :data:`REF_RPM`): thrust x ``(D_ref / D)^p`` (``p`` =
  :data:`DIAMETER_EXPONENT`: thrust proportional to lip length at a given feed per revolution),
  and the feed as the feed at ``REF_RPM`` with the same feed per revolution,
  ``v_eq = v REF_RPM / rpm``; cortical bone gets the midpoint of the densest class's range.
  Their scatter (different bones, species, studies) sets their weight: one common log10 SD
  estimated from the residuals.

Standard errors: the statistical covariance ``(J^T W J)^-1`` at the solution (the torque group's
inflated by its Birge ratio when above 1), plus the systematic part of the two assignments
shared by many points (cortical HU, diameter exponent), each propagated by refitting at +-1 SD.
Harmonics are not in the data: they keep the pine-wood exponents and the pine-wood ratios
``Bk / A0`` at ``C' = 300``, anchored at the cortical assignment (as ``bone-illustrative``).
Every row of the file is either used or excluded with a reason (:data:`EXCLUDED`); a row in
neither is refused, so a new point is never silently ignored.

The Misch bands and where bone begins are imaging's rules (:mod:`ctdrill.imaging.misch`, their
one owner); ``model`` does not import ``imaging``, so :func:`fit_literature` takes them as
arguments from its caller in ``app`` (``ctdrill calibrate --literature``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ctdrill.hu import AIR_HU
from ctdrill.model.literature_data import (
    DIAMETER_EXPONENT,
    EXCLUDED,
    OPEN_HIGH_HU,
    OPEN_LOW_HU,
    REF_DIAMETER_MM,
    REF_RPM,
    SET_NAME,
    THRUST_KEYS,
    TORQUE_KEYS,
    LiteratureData,
    LiteratureError,
    ThrustPoint,
    TorquePoint,
    class_hu_ranges,
    read_literature,
)

__all__ = [
    "DIAMETER_EXPONENT",
    "EXCLUDED",
    "OPEN_HIGH_HU",
    "OPEN_LOW_HU",
    "REF_DIAMETER_MM",
    "REF_RPM",
    "SET_NAME",
    "THRUST_KEYS",
    "TORQUE_KEYS",
    "LiteratureData",
    "LiteratureError",
    "ThrustPoint",
    "TorquePoint",
    "class_hu_ranges",
    "converted_thrust",
    "fit_literature",
    "read_literature",
]

_LN10 = math.log(10.0)
#: Width of the set's gate ramp, HU (as bone-illustrative).
GATE_WIDTH_HU = 50.0


@dataclass(frozen=True)
class Assumptions:
    """The assignments shared by many points (their uncertainty is propagated by refitting)."""

    cortical_hu: float
    diameter_exponent: float


def _uniform_sd(lo: float, hi: float) -> float:
    return (hi - lo) / math.sqrt(12.0)


def converted_thrust(pt: ThrustPoint, diameter_exponent: float) -> tuple[float, float]:
    """``(thrust at REF_DIAMETER_MM in N, equivalent feed at REF_RPM in mm/s)`` of a point."""
    return (
        pt.thrust_n * (REF_DIAMETER_MM / pt.diameter_mm) ** diameter_exponent,
        pt.feed_mm_s * REF_RPM / pt.rpm,
    )


@dataclass(frozen=True)
class _Solution:
    theta: np.ndarray  # b0, n, ke, a_T
    cov: np.ndarray  # (4, 4) statistical
    thrust_sd_log10: float
    torque_birge: float
    residuals_thrust: np.ndarray
    residuals_torque: np.ndarray  # in log10 units


def _solve(
    data: LiteratureData, a: Assumptions, classes: Mapping[str, tuple[float, float]]
) -> _Solution:
    from scipy.optimize import least_squares  # 0.7 s to import: only the fit needs it

    lt = np.array([math.log10(t.torque_ncm) for t in data.torque])
    cp_t = np.array([sum(classes[t.misch]) / 2.0 - AIR_HU for t in data.torque])
    sd_hu_t = np.array([_uniform_sd(*classes[t.misch]) for t in data.torque])
    sem_log = np.array([t.sd_ncm / t.torque_ncm / math.sqrt(t.sites) / _LN10 for t in data.torque])
    conv = [converted_thrust(p, a.diameter_exponent) for p in data.thrust]
    lf = np.log10([c[0] for c in conv])
    veq = np.array([c[1] for c in conv])
    lc_cort = math.log10(a.cortical_hu - AIR_HU)

    def resid(theta: np.ndarray, w_t: np.ndarray, sd_f: float) -> np.ndarray:
        b0, n, ke, at = theta
        r_t = (lt - at - n * np.log10(cp_t)) / w_t
        r_f = (lf - b0 - n * lc_cort - np.log10(1.0 + ke * veq)) / sd_f
        return np.concatenate([r_t, r_f])

    def jac(theta: np.ndarray, w_t: np.ndarray, sd_f: float) -> np.ndarray:
        _, _, ke, _ = theta
        j_t = np.column_stack([0 * lt, -np.log10(cp_t), 0 * lt, -np.ones_like(lt)]) / w_t[:, None]
        j_f = np.column_stack(
            [-np.ones_like(lf), np.full_like(lf, -lc_cort), -veq / ((1 + ke * veq) * _LN10), 0 * lf]
        )
        return np.vstack([j_t, j_f / sd_f])

    theta = np.array([0.0, 3.0, 1.0, 0.0])
    sd_f, birge = 0.1, 1.0
    for _ in range(100):
        w_t = np.hypot(sem_log, theta[1] * sd_hu_t / (cp_t * _LN10)) * birge
        sol = least_squares(
            resid,
            theta,
            jac=jac,
            args=(w_t, sd_f),
            bounds=([-np.inf, -np.inf, 0.0, -np.inf], np.inf),
            xtol=1e-15,
            ftol=1e-15,
            gtol=1e-15,
        )
        r = resid(sol.x, w_t, sd_f)
        nt = lt.shape[0]
        new_sd = float(np.sqrt(np.sum((r[nt:] * sd_f) ** 2) / (lf.shape[0] - 2)))
        chi2 = float(np.sum((r[:nt] * birge) ** 2) / (nt - 2))
        new_birge = max(1.0, math.sqrt(chi2))
        done = (
            abs(new_sd - sd_f) < 1e-13
            and abs(new_birge - birge) < 1e-13
            and bool(np.allclose(sol.x, theta, rtol=0.0, atol=1e-12))
        )
        theta, sd_f, birge = sol.x, new_sd, new_birge
        if done:
            break
    else:  # pragma: no cover - the weights converge in a few rounds on any sane data
        raise LiteratureError("the literature fit's weights did not converge")
    w_t = np.hypot(sem_log, theta[1] * sd_hu_t / (cp_t * _LN10)) * birge
    j = jac(theta, w_t, sd_f)
    r = resid(theta, w_t, sd_f)
    nt = lt.shape[0]
    return _Solution(
        theta=theta,
        cov=np.linalg.inv(j.T @ j),
        thrust_sd_log10=sd_f,
        torque_birge=birge,
        residuals_thrust=r[nt:] * sd_f,
        residuals_torque=r[:nt] * w_t,
    )


def _sig(x: float, digits: int = 8) -> float:
    return float(f"{x:.{digits}g}")


def _harmonics(anchor_c_prime: float, a0_at_anchor_n: float) -> list[dict[str, Any]]:
    """Pine-wood exponents and ratios ``Bk / A0`` at C' = 300, anchored at the cortical value."""
    from ctdrill.model.calibration import load_calibration

    pine = load_calibration("pine-wood-paper")
    pine_a0 = 10.0 ** (pine.a0.b0 + pine.a0.n * math.log10(300.0))
    out = []
    for h in pine.harmonics:
        ratio = 10.0 ** (h.b0 + h.n * math.log10(300.0)) / pine_a0
        b0 = math.log10(ratio * a0_at_anchor_n) - h.n * math.log10(anchor_c_prime)
        out.append({"order": h.order, "b0": _sig(b0, 6), "n": h.n})
    return out


def fit_literature(
    path: str | Path, *, bands_hu: Sequence[tuple[str, float, float]], gate_hu: float
) -> dict[str, Any]:
    """Fit ``bone-literature`` to the literature file; the set's JSON document.

    Parameters
    ----------
    path : the literature file (``bone_force_points.csv``).
    bands_hu : the bone-density classes ``(class, low HU, high HU)``, densest first, outer ends
        open: :data:`ctdrill.imaging.misch.MISCH_BANDS_HU`. The torque points name them; the
        densest is cortical bone (:func:`class_hu_ranges` closes the open ends).
    gate_hu : where bone begins, HU (:data:`ctdrill.imaging.misch.BONE_HU`): the set's gate,
        below which nothing is cut.

    The document is a calibration set (:func:`ctdrill.model.calibration.calibration_from_dict`
    loads it) with ``fit`` (value, standard error and % per parameter), ``covariance`` of
    ``a0.b0, a0.n, a0.ke`` (statistical + systematic) and ``provenance`` (the method, every
    point used with its conversion and residual, every point excluded with its reason, the
    assumptions and checks against points not fitted).
    """
    classes = class_hu_ranges(bands_hu)
    cortical = bands_hu[0][0]
    data = read_literature(path, classes)
    cort_mid = sum(classes[cortical]) / 2.0
    base = Assumptions(cort_mid, DIAMETER_EXPONENT[0])
    sol = _solve(data, base, classes)
    shifts = {
        "cortical_hu": (_uniform_sd(*classes[cortical]), "cortical HU"),
        "diameter_exponent": (DIAMETER_EXPONENT[1], "diameter exponent"),
    }
    cov_sys = np.zeros((3, 3))
    sys_se: dict[str, dict[str, float]] = {}
    for field, (sd, _) in shifts.items():

        def refit(delta: float, field: str = field) -> np.ndarray:
            kw = {"cortical_hu": base.cortical_hu, "diameter_exponent": base.diameter_exponent}
            kw[field] += delta
            return _solve(data, Assumptions(**kw), classes).theta[:3]

        d = (refit(sd) - refit(-sd)) / 2.0
        cov_sys += np.outer(d, d)
        sys_se[field] = {k: _sig(abs(v), 6) for k, v in zip(("b0", "n", "ke"), d, strict=True)}
    cov = sol.cov[:3, :3] + cov_sys
    cov = (cov + cov.T) / 2.0
    names = ("a0.b0", "a0.n", "a0.ke")
    b0, n, ke = (float(v) for v in sol.theta[:3])
    anchor_cp = cort_mid - AIR_HU
    a0_anchor = 10.0 ** (b0 + n * math.log10(anchor_cp))
    conv = [converted_thrust(p, base.diameter_exponent) for p in data.thrust]
    veqs = [c[1] for c in conv]
    se = np.sqrt(np.diag(cov))
    doc: dict[str, Any] = {
        "name": SET_NAME,
        "material": "bone (literature fit: cortical thrust in human and porcine femur and one "
        "unspecified bone; cancellous drilling torque in bovine rib)",
        "source": f"fitted by ctdrill.model.literature to {len(data.thrust)} published cortical "
        f"thrust points and {len(data.torque)} Misch-class drilling torques in "
        f"{data.file_name} (sha256 {data.sha256[:12]}); a literature fit, not measured with "
        "this drill",
        "c_prime_range": [OPEN_LOW_HU - AIR_HU, OPEN_HIGH_HU - AIR_HU],
        "feed_range_mm_s": [_sig(min(veqs), 4), _sig(max(veqs), 4)],
        "gate_hu": gate_hu,
        "gate_width_hu": GATE_WIDTH_HU,
        "a0": {"b0": _sig(b0), "n": _sig(n), "ke": _sig(ke)},
        "harmonics": _harmonics(anchor_cp, a0_anchor),
        "fit": {
            key: {
                "value": _sig(v),
                "stderr": _sig(float(s), 6),
                "stderr_pct": _sig(100.0 * float(s) / abs(v), 4),
            }
            for key, v, s in zip(names, (b0, n, ke), se, strict=True)
        },
        "covariance": {
            "parameters": list(names),
            "matrix": [[_sig(float(v), 8) for v in row] for row in cov],
        },
        "provenance": _provenance(data, sol, base, sys_se, conv, classes, cortical, gate_hu),
    }
    return doc


def _provenance(
    data: LiteratureData,
    sol: _Solution,
    base: Assumptions,
    sys_se: Mapping[str, Mapping[str, float]],
    conv: Sequence[tuple[float, float]],
    classes: Mapping[str, tuple[float, float]],
    cortical: str,
    gate_hu: float,
) -> dict[str, Any]:
    b0, n, ke, at = (float(v) for v in sol.theta)
    lo_hu, hi_hu = classes[cortical]
    torque_classes = list(dict.fromkeys(t.misch for t in data.torque))
    midpoints = ", ".join(f"{c} {sum(classes[c]) / 2.0:g}" for c in torque_classes)
    cov_stat = sol.cov[:3, :3]

    def a0(hu: float, v: float) -> float:
        return 10.0 ** (b0 + n * math.log10(hu - AIR_HU)) * (1.0 + ke * v)

    def ratio(v1: float, v2: float) -> float:
        return (1.0 + ke * v2) / (1.0 + ke * v1)

    cort = base.cortical_hu
    return {
        "method": (
            f"least-squares fit of A0 = 10^b0 C'^n (1 + Ke v) to {len(data.thrust)} published "
            f"cortical thrust points (converted to a {REF_DIAMETER_MM:g} mm drill at "
            f"{REF_RPM:g} rpm) and {len(data.torque)} Misch-class drilling torques (slope n "
            "only); literature-grounded, not measured: expect a factor of about 2-3 either way"
        ),
        "fitted_by": "ctdrill.model.literature.fit_literature",
        "data_file": data.file_name,
        "data_sha256": data.sha256,
        "reference_drill": {"diameter_mm": REF_DIAMETER_MM, "rpm": REF_RPM},
        "conversions": [
            f"diameter: thrust x (D_ref / D)^p, D_ref = {REF_DIAMETER_MM:g} mm, p = "
            f"{DIAMETER_EXPONENT[0]:g} +- {DIAMETER_EXPONENT[1]:g} (thrust proportional to lip "
            "length at a given feed per revolution; the SD is a judgement, propagated)",
            f"feed per revolution: v_eq = v x {REF_RPM:g} / rpm, the feed at {REF_RPM:g} rpm "
            "with the study's feed per revolution; Ke applies to v_eq",
            f"HU of cortical bone: {base.cortical_hu:g} (midpoint of {lo_hu:g}-"
            f"{hi_hu:g} HU, Misch {cortical} to dense cortical bone; none of the studies "
            "reports HU) +- width / sqrt(12), propagated by refitting",
            f"HU of a Misch class: its midpoint ({midpoints}; the study "
            "reports classes, not HU) with SD width / sqrt(12) entering through the slope",
            "torque for thrust: only the slope n is taken from torque (its level a_T is a "
            "separate parameter): both assumed proportional to the specific cutting pressure",
        ],
        "points_used": [
            {
                "source_key": p.key,
                "group": "thrust",
                "why": THRUST_KEYS[p.key],
                "thrust_n": p.thrust_n,
                "thrust_at_ref_drill_n": _sig(c[0], 6),
                "feed_at_ref_rpm_mm_s": _sig(c[1], 6),
                "hu_assigned": base.cortical_hu,
                "residual_log10": _sig(float(r), 4),
            }
            for p, c, r in zip(data.thrust, conv, sol.residuals_thrust, strict=True)
        ]
        + [
            {
                "source_key": t.key,
                "group": "torque (slope only)",
                "torque_ncm": t.torque_ncm,
                "sem_ncm": _sig(t.sd_ncm / math.sqrt(t.sites), 4),
                "misch": t.misch,
                "hu_assigned": sum(classes[t.misch]) / 2.0,
                "residual_log10": _sig(float(r), 4),
            }
            for t, r in zip(data.torque, sol.residuals_torque, strict=True)
        ],
        "points_excluded": [{"source_key": k, "reason": why} for k, why in data.excluded],
        "scatter": {
            "thrust_sd_log10": _sig(sol.thrust_sd_log10, 4),
            "torque_birge_ratio": _sig(sol.torque_birge, 4),
            "torque_level_a_t": _sig(at, 6),
        },
        "stderr_statistical": {
            k: _sig(math.sqrt(cov_stat[i, i]), 6) for i, k in enumerate(("b0", "n", "ke"))
        },
        "stderr_systematic": dict(sys_se),
        "checks": [
            {
                "source_key": "ABJS_feed_ratio",
                "quoted": "thrust +335 % from 0.5 to 3 mm/s (ratio 4.35, or 3.35)",
                "predicted_ratio_same_rpm": _sig(ratio(0.5, 3.0), 4),
            },
            {
                "source_key": "DogJaw_MS / DogJaw_HSS",
                "quoted": "1.5-4.9 N, dental implant drills in dog jaw cortical bone",
                "predicted_n": f"{a0(cort, 0.0):.3g} N at zero feed, {a0(cort, 0.4):.3g} N at "
                f"0.4 mm/s (HU {cort:g}, {REF_DIAMETER_MM:g} mm drill, {REF_RPM:g} rpm): the "
                "femur studies' feeds per revolution give far more than the dental drills",
            },
        ],
        "harmonics": "not in the literature data: pine-wood exponents and the pine-wood ratios "
        "Bk / A0 at C' = 300, anchored at the cortical assignment; no uncertainty given",
        "gate": f"{gate_hu:g} +- {GATE_WIDTH_HU / 2.0:g} HU as bone-illustrative: below it (soft "
        f"tissue, the canal's contents) nothing is cut; {list(classes)[-1]} bone (< {gate_hu:g} "
        "HU) is therefore mostly not cut, although its torque point informs the slope",
    }
