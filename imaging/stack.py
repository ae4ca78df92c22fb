"""Rules about a stack's slice positions: the one owner of "irregular", "gap" and "regular".

A stack's slices sit at true positions ``p_k`` along the slice normal (IPP projected on the
IOP normal, mm). The *nominal step* is the median of the steps ``p_{k+1} - p_k``.

- A step is **irregular** when it differs from the nominal step by more than
  :data:`STEP_RTOL` of it (the loader reports ``nonuniform_spacing`` / ``slice_gap``).
- A step is a **gap for the drill** when it is wider than :data:`GAP_FACTOR` times the nominal
  step: a drill lip that crosses it is refused unless the user asks to interpolate across it.
- A stack is **regular** when one (4, 4) affine with the nominal step places every slice within
  :data:`AFFINE_TOL_MM` (and within STEP_RTOL of a step) of its true position; only then is
  ``affine_lps`` a true description of the whole stack (``ctdrill inspect`` says ``regular``).

Importing this module loads no NumPy (the functions import it): the CLI's help quotes
:data:`GAP_FACTOR`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np

#: Relative tolerance on a slice step before it counts as irregular.
STEP_RTOL = 0.01
#: A step wider than this many nominal steps is a gap the drill may not cross silently.
GAP_FACTOR = 1.5
#: Largest distance, mm, between a slice's true position and the regular affine's position
#: for the stack to be called regular.
AFFINE_TOL_MM = 0.01


def median(values: np.ndarray) -> float:
    """``float(np.median(values))`` of a 1-D array, the same value (the middle element, or the
    two middle ones' sum halved; NaN if any is NaN), without ``np.median``'s import of
    ``numpy.ma`` (7-9 ms of a fresh export's start)."""
    import numpy as np

    v = np.sort(np.asarray(values, dtype=np.float64).reshape(-1))
    if v.size == 0 or np.isnan(v[-1]):
        return float("nan")
    mid = v.size // 2
    if v.size % 2:
        return float(v[mid])
    return float((v[mid - 1] + v[mid]) / 2.0)


def _steps(positions_mm: np.ndarray) -> np.ndarray:
    import numpy as np

    return np.diff(np.asarray(positions_mm, dtype=np.float64).reshape(-1))


def nominal_step_mm(positions_mm: np.ndarray) -> float:
    """Median slice step, mm (signed as the positions run; 0.0 for fewer than 2 slices)."""

    steps = _steps(positions_mm)
    return median(steps) if steps.size else 0.0


def irregular_steps(positions_mm: np.ndarray) -> np.ndarray:
    """(S-1,) bool: step ``k -> k+1`` differs from the nominal step by more than STEP_RTOL."""
    import numpy as np

    steps = _steps(positions_mm)
    if steps.size == 0:
        return np.zeros(0, dtype=bool)
    med = median(steps)
    out: np.ndarray = np.abs(steps - med) > STEP_RTOL * abs(med)
    return out


def wide_steps(positions_mm: np.ndarray) -> np.ndarray:
    """(S-1,) bool: step ``k -> k+1`` is wider than GAP_FACTOR nominal steps (a drill gap)."""
    import numpy as np

    steps = _steps(positions_mm)
    if steps.size == 0:
        return np.zeros(0, dtype=bool)
    med = median(steps)
    out: np.ndarray = np.abs(steps) > GAP_FACTOR * abs(med)
    return out


def affine_residual_mm(positions_mm: np.ndarray) -> float:
    """Largest distance between ``p_k`` and ``p_0 + k * nominal step``, mm (0 for one slice)."""
    import numpy as np

    pos = np.asarray(positions_mm, dtype=np.float64).reshape(-1)
    if pos.size < 2:
        return 0.0
    med = nominal_step_mm(pos)
    return float(np.max(np.abs(pos - (pos[0] + med * np.arange(pos.size)))))


def is_regular(positions_mm: np.ndarray) -> bool:
    """True when the nominal-step affine places every slice within AFFINE_TOL_MM and within
    STEP_RTOL of a step."""
    tol = min(AFFINE_TOL_MM, STEP_RTOL * abs(nominal_step_mm(positions_mm)))
    return affine_residual_mm(positions_mm) <= tol


def piecewise_linear(x: np.ndarray, xp: np.ndarray, fp: np.ndarray) -> np.ndarray:
    """``np.interp`` on ascending ``xp`` with linear extrapolation by the end segments.

    NaN stays NaN and infinities stay infinite (so such points remain outside any hull).
    """
    import numpy as np

    xv = np.asarray(x, dtype=np.float64)
    out = np.asarray(np.interp(xv, xp, fp), dtype=np.float64)
    if xp.size < 2:
        return out
    with np.errstate(invalid="ignore"):
        lo = xv < xp[0]
        hi = xv > xp[-1]
    if lo.any():
        slope = (fp[1] - fp[0]) / (xp[1] - xp[0])
        out[lo] = fp[0] + (xv[lo] - xp[0]) * slope
    if hi.any():
        slope = (fp[-1] - fp[-2]) / (xp[-1] - xp[-2])
        out[hi] = fp[-1] + (xv[hi] - xp[-1]) * slope
    return out
