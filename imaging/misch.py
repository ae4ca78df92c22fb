"""Misch bone-density classes by CT number: the one owner of the bands (DESIGN.md section 5).

D1 > 1250 HU, D2 850-1250, D3 350-850, D4 150-350, D5 < 150. A value on a boundary belongs to
the band above it except at 1250, which D1 excludes ("> 1250"): 1250 is D2, 850 is D2, 350 is
D3, 150 is D4. Export tables, plots and the GUI all classify with :func:`misch_class`.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

#: The classes, densest first.
MISCH_CLASSES: tuple[str, ...] = ("D1", "D2", "D3", "D4", "D5")
#: (class, low HU, high HU), densest first; the outer bands are open (infinite ends).
MISCH_BANDS_HU: tuple[tuple[str, float, float], ...] = (
    ("D1", 1250.0, math.inf),
    ("D2", 850.0, 1250.0),
    ("D3", 350.0, 850.0),
    ("D4", 150.0, 350.0),
    ("D5", -math.inf, 150.0),
)


def misch_class(hu: ArrayLike) -> np.ndarray:
    """Misch class of each CT number (see the module docstring for the boundaries).

    Parameters
    ----------
    hu : scalar or array of HU.

    Returns
    -------
    str array (``<U2``) of ``D1`` .. ``D5``, the shape of ``hu`` (0-d for a scalar; ``str()``
    of it gives the class). NaN is ``D5``.
    """
    h = np.asarray(hu, dtype=np.float64)
    out = np.full(h.shape, "D5", dtype="<U2")
    for name, lo, _ in reversed(MISCH_BANDS_HU[:-1]):
        out = np.where(h > lo if name == "D1" else h >= lo, name, out)
    return out


def _band_low_hu(name: str) -> float:
    return next(lo for cls, lo, _ in MISCH_BANDS_HU if cls == name)


#: Where bone begins: the lower edge of D4, the least dense band that soft tissue (about 40 HU)
#: and the canal's contents cannot reach. ``ctdrill suggest`` finds the bone surface where a
#: line first reaches it (:func:`is_bone`: class D4 or denser, i.e. ``HU >= 150``).
BONE_HU: float = _band_low_hu("D4")
#: Where cortical bone begins: the lower edge of D1, Misch's dense cortical class
#: (:func:`is_cortical`: class D1, i.e. ``HU > 1250``).
CORTICAL_HU: float = _band_low_hu("D1")


def is_bone(hu: ArrayLike) -> np.ndarray:
    """True where the CT number is in class D4 or denser (``HU >= BONE_HU``); NaN is False."""
    return np.asarray(np.asarray(hu, dtype=np.float64) >= BONE_HU)


def is_cortical(hu: ArrayLike) -> np.ndarray:
    """True where the CT number is in class D1 (``HU > CORTICAL_HU``); NaN is False."""
    return np.asarray(np.asarray(hu, dtype=np.float64) > CORTICAL_HU)
