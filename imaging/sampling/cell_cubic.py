"""The trilinear CT along a ray inside one cell, as a cubic in the distance (numba helpers).

Inside one trilinear cell the field along a straight ray is a cubic polynomial of the distance
``t``: :func:`cell_cubic` writes its four coefficients for a stretch of a ray that stays
inside one cell (kept :data:`~ctdrill.imaging.sampling.hu_blocks.MARGIN_VOX` from its faces
and the CT's hull). A bisection of a threshold crossing (the bone walls' exit crossing,
:mod:`~ctdrill.imaging.sampling.envelope_kernel`) then reads each midpoint in a few
multiplications instead of eight voxels and their weights. The cubic differs from the exact
point's trilinear sample by rounding (~1e-10 HU for CT numbers of a few thousand HU), so its
caller takes it only where it lies farther than a guard (the kernels' ``eps_hu``, >= 1e-3 HU)
from every threshold it decides on and reads the exact sample elsewhere: every decision, and
so every bisected wall, is the exact samples' bit for bit.
"""

from __future__ import annotations

import math

import numpy as np

from ctdrill.imaging.sampling.hu_blocks import MARGIN_VOX
from ctdrill.jit import helper


@helper
def _cell_of(c: float, d: float, t_span: float, top: float) -> int:  # pragma: no cover
    """The cell index along one axis holding ``c + s d`` for every ``s`` in ``[0, t_span]``
    :data:`MARGIN_VOX` inside its faces and the hull ``[0, top]``, else -1."""
    end = c + t_span * d
    lo_c = min(c, end)
    hi_c = max(c, end)
    if not (lo_c >= MARGIN_VOX and hi_c <= top - MARGIN_VOX):
        return -1
    cell = math.floor(lo_c)
    if lo_c < cell + MARGIN_VOX or hi_c > cell + 1.0 - MARGIN_VOX:
        return -1
    return int(cell)


@helper
def cell_cubic(
    vol: np.ndarray,
    top: np.ndarray,
    ci: float,
    cj: float,
    ck: float,
    ei: float,
    ej: float,
    ek: float,
    t_span: float,
    coef: np.ndarray,
) -> bool:  # pragma: no cover - compiled; tested against the exact samples
    """Write into ``coef`` (4,) the cubic ``coef[0] + s (coef[1] + s (coef[2] + s coef[3]))``
    of the trilinear field at index coordinates ``(ci, cj, ck) + s (ei, ej, ek)`` for ``s`` in
    ``[0, t_span]``; False (``coef`` untouched) when that stretch is not inside one cell."""
    si = _cell_of(ci, ei, t_span, top[0])
    sj = _cell_of(cj, ej, t_span, top[1])
    sk = _cell_of(ck, ek, t_span, top[2])
    if si < 0 or sj < 0 or sk < 0:
        return False
    f000 = float(vol[sk, sj, si])
    f100 = float(vol[sk, sj, si + 1])
    f010 = float(vol[sk, sj + 1, si])
    f110 = float(vol[sk, sj + 1, si + 1])
    f001 = float(vol[sk + 1, sj, si])
    f101 = float(vol[sk + 1, sj, si + 1])
    f011 = float(vol[sk + 1, sj + 1, si])
    f111 = float(vol[sk + 1, sj + 1, si + 1])
    # f = A + B u + C v + D w + E uv + F uw + G vw + H uvw (u along i, v along j, w along k)
    b_ = f100 - f000
    c_ = f010 - f000
    d_ = f001 - f000
    e_ = f110 - f100 - f010 + f000
    f_ = f101 - f100 - f001 + f000
    g_ = f011 - f010 - f001 + f000
    h_ = f111 - f110 - f101 - f011 + f100 + f010 + f001 - f000
    u, v, w = ci - si, cj - sj, ck - sk
    coef[0] = f000 + b_ * u + c_ * v + d_ * w + e_ * u * v + f_ * u * w + g_ * v * w
    coef[0] += h_ * u * v * w
    coef[1] = b_ * ei + c_ * ej + d_ * ek + e_ * (u * ej + v * ei) + f_ * (u * ek + w * ei)
    coef[1] += g_ * (v * ek + w * ej) + h_ * (ei * v * w + u * ej * w + u * v * ek)
    coef[2] = e_ * ei * ej + f_ * ei * ek + g_ * ej * ek
    coef[2] += h_ * (ei * ej * w + ei * v * ek + u * ej * ek)
    coef[3] = h_ * ei * ej * ek
    return True
