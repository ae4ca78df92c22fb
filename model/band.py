"""A 68 % band of the mean cutting force from a set's covariance and an HU uncertainty.

The mean cutting force at feed ``v`` is ``M(x) = S0(x) (1 + Ke v)`` with
``S0 = sum_r w_r mean_a g(HU) 10^b0 C'^n`` (:mod:`ctdrill.model.profile`). Its uncertainty is
propagated to first order **in log space**: ``sd(ln M)^2 = J_p^T Sigma_p J_p + J_h^T Sigma_h J_h``
with

- ``d ln M / d b0 = ln 10``, ``d ln M / d n = sum w g A0 ln C' / S0``,
  ``d ln M / d Ke = v / (1 + Ke v)`` and ``Sigma_p`` the set's covariance
  (:class:`ctdrill.model.calibration_cov.ParameterCovariance`);
- an HU error linear in HU, ``dHU = e0 + e1 HU`` (a constant offset, a wrong slope of a grey
  map) with covariance ``Sigma_h`` of ``(e0, e1)`` (:class:`HuUncertainty`), shared by every
  sample of the path (a calibration error of the series, not noise that averages out):
  ``d ln M / d e0 = sum w dF/dHU / S0``, ``d ln M / d e1 = sum w HU dF/dHU / S0``, with
  ``dF/dHU = g' A0 + g A0 n / C'`` (``g'`` the gate's slope; the law is flat where ``C'`` is
  clipped).

The band is ``M exp(-sd) .. M exp(+sd)``: multiplicative (a force is never negative; ``b0`` is a
log10 parameter, so its part is exact) and equal to the first-order linear band ``M +- M sd``
to first order. Where nothing is cut (``S0 = 0``) the band is ``[0, 0]``: to first order the
gate's slope is zero there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ctdrill.hu import AIR_HU
from ctdrill.model.calibration import Calibration
from ctdrill.model.errors import ModelInputError
from ctdrill.model.force import feed_factor, gate

#: The band's coverage: one standard deviation of a normal, 68.27 %.
BAND_LEVEL: float = 0.6827
_LN10 = math.log(10.0)


@dataclass(frozen=True)
class HuUncertainty:
    """An HU error ``dHU = e0 + e1 HU`` shared by the whole series.

    Attributes
    ----------
    cov : ((var e0, cov), (cov, var e1))
        Covariance of ``e0`` (HU) and ``e1`` (dimensionless), symmetric and PSD.
    source : str
        Where it comes from (``"--hu-sigma 30"``, ``"grey map (2 regions)"``), for the outputs.
    """

    cov: tuple[tuple[float, float], tuple[float, float]]
    source: str

    def __post_init__(self) -> None:
        m = np.array(self.cov, dtype=np.float64)
        if m.shape != (2, 2) or not np.all(np.isfinite(m)):
            raise ModelInputError("HU uncertainty: the covariance must be 2 x 2 and finite")
        if abs(m[0, 1] - m[1, 0]) > 1e-12 * (abs(m[0, 1]) + 1e-300) or min(m[0, 0], m[1, 1]) < 0:
            raise ModelInputError(
                "HU uncertainty: the covariance must be symmetric, variances >= 0"
            )
        if np.linalg.eigvalsh(m)[0] < -1e-9 * max(float(np.max(np.abs(m))), 1e-300):
            raise ModelInputError("HU uncertainty: the covariance is not positive semi-definite")

    @staticmethod
    def offset(sigma_hu: float, source: str) -> HuUncertainty:
        """A constant HU offset of SD ``sigma_hu`` (``--hu-sigma``)."""
        s = float(sigma_hu)
        if not (math.isfinite(s) and s >= 0.0):
            raise ModelInputError(f"HU sigma must be a finite number >= 0 HU, got {sigma_hu!r}")
        return HuUncertainty(((s * s, 0.0), (0.0, 0.0)), source)

    def plus(self, other: HuUncertainty) -> HuUncertainty:
        """Both errors, independent: covariances add, sources are joined."""
        a, b = np.array(self.cov), np.array(other.cov)
        c = a + b
        return HuUncertainty(
            ((float(c[0, 0]), float(c[0, 1])), (float(c[1, 0]), float(c[1, 1]))),
            f"{self.source} + {other.source}",
        )

    def sd_hu_at(self, hu: float) -> float:
        """SD of the HU error at ``hu``, HU."""
        j = np.array([1.0, float(hu)])
        return math.sqrt(max(float(j @ np.array(self.cov) @ j), 0.0))


@dataclass(frozen=True, eq=False)
class LipSensitivity:
    """Per-depth lip sums the band needs, arrays of shape (D,).

    ``s0_n``: ``sum w g A0``; ``s0_ln_n``: ``sum w g A0 ln C'`` (``C'`` clipped);
    ``d0_n_per_hu``: ``sum w dF/dHU``; ``d1_n``: ``sum w HU dF/dHU`` (``A0`` at zero feed).
    """

    s0_n: np.ndarray
    s0_ln_n: np.ndarray
    d0_n_per_hu: np.ndarray
    d1_n: np.ndarray


def lip_sensitivity(
    lip_hu: ArrayLike, ring_weights: ArrayLike, calibration: Calibration
) -> LipSensitivity:
    """The sums of :class:`LipSensitivity` over lip samples ``(D, R, A)`` (HU) with the ring
    weights ``(R,)`` or ``(D, R)`` (a drill of a sequence: rings on the cut part of the lip) of
    :func:`ctdrill.model.profile.build_profile` (same quadrature)."""
    hu = np.asarray(lip_hu, dtype=np.float64)
    w = np.asarray(ring_weights, dtype=np.float64)
    if hu.ndim != 3 or w.shape not in ((hu.shape[1],), hu.shape[:2]):
        raise ModelInputError(
            f"lip_hu {hu.shape} (D, R, A) and ring_weights {w.shape} ((R,) or (D, R)) disagree"
        )
    ring_w = w / hu.shape[2]

    def lip_mean(values: np.ndarray) -> np.ndarray:
        if ring_w.ndim == 2:
            return np.asarray(np.einsum("dr,dr->d", values.sum(axis=2), ring_w))
        return np.asarray(values.sum(axis=2) @ ring_w)

    g = gate(hu, calibration)
    width = calibration.gate_width_hu
    lo_gate = calibration.gate_hu - 0.5 * width
    g_slope = np.where((hu > lo_gate) & (hu < lo_gate + width), 1.0 / width, 0.0)
    lo, hi = calibration.c_prime_range
    cp = hu - AIR_HU
    inside = (cp > lo) & (cp < hi)
    cp_c = np.clip(cp, lo, hi)
    law = calibration.a0
    a0 = np.exp(_LN10 * (law.b0 + law.n * np.log10(cp_c)))
    df = g_slope * a0 + np.where(inside, g * a0 * law.n / cp_c, 0.0)
    return LipSensitivity(
        s0_n=lip_mean(g * a0),
        s0_ln_n=lip_mean(g * a0 * np.log(cp_c)),
        d0_n_per_hu=lip_mean(df),
        d1_n=lip_mean(df * hu),
    )


@dataclass(frozen=True, eq=False)
class ForceBand:
    """The mean cutting force and its 68 % band at one feed, arrays of shape (D,).

    ``sd_log_cal`` and ``sd_log_hu`` are the two parts of ``sd_log`` (in quadrature), in natural
    log units (0.1 = about 10 %).
    """

    feed_mm_s: float
    mean_n: np.ndarray
    lo_n: np.ndarray
    hi_n: np.ndarray
    sd_log: np.ndarray
    sd_log_cal: np.ndarray
    sd_log_hu: np.ndarray
    hu: HuUncertainty | None


def force_band(
    sens: LipSensitivity,
    calibration: Calibration,
    feed_mm_s: float,
    hu: HuUncertainty | None = None,
    *,
    s0_n: ArrayLike | None = None,
) -> ForceBand | None:
    """The 68 % band of ``S0 (1 + Ke v)`` (module docstring); None when the set has no
    covariance (an HU uncertainty alone would present the calibration as certain).

    ``s0_n`` (D,) is the centre's ``S0`` when the caller's profile holds its own (the relative
    sensitivities still come from ``sens``); default ``sens.s0_n``.
    """
    cov = calibration.covariance
    if cov is None:
        return None
    factor = float(feed_factor(feed_mm_s, ke_per_mm_s=calibration.ke_per_mm_s))
    v_hat = (factor - 1.0) / calibration.ke_per_mm_s if calibration.ke_per_mm_s > 0 else 0.0
    s0 = sens.s0_n
    cut = s0 > 0.0
    safe = np.where(cut, s0, 1.0)
    grads = {
        "a0.b0": np.full_like(s0, _LN10),
        "a0.n": sens.s0_ln_n / safe,
        "a0.ke": np.full_like(s0, v_hat / factor),
    }
    j = np.stack([grads[name] for name in cov.parameters])  # (P, D)
    var_cal = np.einsum("pd,pq,qd->d", j, cov.array(), j)
    if hu is not None:
        jh = np.stack([sens.d0_n_per_hu / safe, sens.d1_n / safe])
        var_hu = np.einsum("pd,pq,qd->d", jh, np.array(hu.cov), jh)
    else:
        var_hu = np.zeros_like(s0)
    sd_cal = np.where(cut, np.sqrt(np.clip(var_cal, 0.0, None)), 0.0)
    sd_hu = np.where(cut, np.sqrt(np.clip(var_hu, 0.0, None)), 0.0)
    sd = np.hypot(sd_cal, sd_hu)
    centre = s0 if s0_n is None else np.asarray(s0_n, dtype=np.float64)
    if centre.shape != s0.shape:
        raise ModelInputError(f"s0_n has shape {centre.shape}, the lip sums {s0.shape}")
    mean = centre * factor
    return ForceBand(
        feed_mm_s=float(feed_mm_s),
        mean_n=mean,
        lo_n=mean * np.exp(-sd),
        hi_n=mean * np.exp(sd),
        sd_log=sd,
        sd_log_cal=sd_cal,
        sd_log_hu=sd_hu,
        hu=hu,
    )
