"""The bisection of :meth:`~ctdrill.imaging.sampling.arch.ArchCurve.project` for one point,
compiled: the same IEEE operations as its Python-float path (``_point_one``, ``_g_one``,
``_bisect_one``), so the same bits; that path stays the reference (tests hold them equal)."""

from __future__ import annotations

import math

import numpy as np

from ctdrill.jit import Kernel, helper


@helper
def _point(cum: np.ndarray, xy: np.ndarray, s_mm: float) -> tuple[float, float]:  # pragma: no cover
    """``ArchCurve._point_one``."""
    last = cum.shape[0] - 1
    s = min(max(s_mm, 0.0), cum[last])
    seg = min(max(np.searchsorted(cum, s, side="right") - 1, 0), last - 1)
    f = (s - cum[seg]) / (cum[seg + 1] - cum[seg])
    x0, y0, x1, y1 = xy[seg, 0], xy[seg, 1], xy[seg + 1, 0], xy[seg + 1, 1]
    return x0 + f * (x1 - x0), y0 + f * (y1 - y0)


@helper
def _g(
    cum: np.ndarray, xy: np.ndarray, half: float, x: float, y: float, s_mm: float
) -> float:  # pragma: no cover - compiled
    """``ArchCurve._g_one``."""
    if half == 0.0:
        last = cum.shape[0] - 1
        seg = min(max(np.searchsorted(cum, s_mm, side="right") - 1, 0), last - 1)
        cx, cy = xy[seg + 1, 0] - xy[seg, 0], xy[seg + 1, 1] - xy[seg, 1]
    else:
        px, py = _point(cum, xy, s_mm + half)
        qx, qy = _point(cum, xy, s_mm - half)
        cx, cy = px - qx, py - qy
    norm = math.sqrt(cx * cx + cy * cy)
    px, py = _point(cum, xy, s_mm)
    return (x - px) * (cx / norm) + (y - py) * (cy / norm)


def _bisect_kernel(
    cum: np.ndarray,
    xy: np.ndarray,
    half: float,
    x: float,
    y: float,
    a: float,
    b: float,
    ga: float,
    steps: int,
    out: np.ndarray,
) -> None:  # pragma: no cover - compiled; tested against the Python path
    for _ in range(steps):
        m = 0.5 * (a + b)
        gm = _g(cum, xy, half, x, y, m)
        if (ga <= 0.0) == (gm <= 0.0):
            a, ga = m, gm
        else:
            b = m
    out[0] = a
    out[1] = b


_SIG = (
    "void(float64[::1], float64[:, ::1], float64, float64, float64, float64, float64, "
    "float64, int64, float64[::1])"
)
ARCH_KERNEL = Kernel(_bisect_kernel, [_SIG], readonly=(0, 1))
