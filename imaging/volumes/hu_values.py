"""Whether a volume file's values are Hounsfield units: the rule, and the low tail it reads.

NIfTI, NRRD and MetaImage carry no unit for their values. :func:`hu_problem` owns the rule
(:mod:`.load` applies it to every file volume): values that never go below 0, that span less
than :data:`MIN_HU_SPAN`, or whose low tail (the :data:`LOW_TAIL_PERCENT` % lowest of at most
``_TAIL_SAMPLES`` voxels sampled evenly, :func:`tail_step`) stays at or above
:data:`MIN_HU_LOW_TAIL` are not HU. A reader that samples the voxels as it reads them
(:class:`.identity.HuStream`) takes the same sample.
"""

from __future__ import annotations

import numpy as np

#: Values spanning less than this cannot be a CT in HU (air -1000 to bone hundreds).
MIN_HU_SPAN = 100.0
#: The low tail of a volume's values: this fraction of the voxels, %. A few padding or
#: outlier voxels below 0 do not make grey values HU.
LOW_TAIL_PERCENT = 0.1
#: A low tail at or above this cannot be a CT in HU: no air (-1000) and no fat (about -100)
#: in more than ``LOW_TAIL_PERCENT`` of the voxels; grey values whose air reads near 0.
MIN_HU_LOW_TAIL = -50.0
#: Voxels sampled (evenly) for the low tail.
_TAIL_SAMPLES = 1 << 20


def hu_problem(lo: float, hi: float, low_tail: float | None = None) -> str | None:
    """Why values spanning ``lo..hi`` cannot be Hounsfield units, or None when they can be.

    ``low_tail`` is the value below which lie ``LOW_TAIL_PERCENT`` % of the voxels (None:
    ``lo``): at or above ``MIN_HU_LOW_TAIL`` the volume has no air and no fat, whatever a few
    voxels below 0 say (grey values with air near 0, and noise or padding just below it).
    """
    if lo >= 0.0:
        return (
            f"values {lo:g}..{hi:g} never go below 0 (a CT in HU has air at -1000 and fat below "
            "0): grey values, not HU"
        )
    if hi - lo < MIN_HU_SPAN:
        return (
            f"values {lo:g}..{hi:g} span less than {MIN_HU_SPAN:g}: normalised intensities, not HU"
        )
    if low_tail is not None and low_tail >= MIN_HU_LOW_TAIL:
        return (
            f"values {lo:g}..{hi:g}, but {100 - LOW_TAIL_PERCENT:g} % of the voxels are at or "
            f"above {low_tail:g} (a CT in HU has air at -1000 and fat near -100): grey values "
            "with air near 0, not HU"
        )
    return None


def tail_step(n_voxels: int) -> int:
    """Every how many-th voxel (flat C order, from the first) the low tail samples: at most
    ``_TAIL_SAMPLES`` of ``n_voxels``, evenly spaced."""
    return max(1, int(n_voxels) // _TAIL_SAMPLES)


def _tail_sample(values: np.ndarray) -> np.ndarray:
    """The low tail's sample of ``values`` (any shape): a strided view (:func:`tail_step`)."""
    flat = values.reshape(-1)
    return flat[:: tail_step(flat.size)]


def tail_below(values: np.ndarray, bound: float, *, sample: np.ndarray | None = None) -> bool:
    """True when :func:`low_tail` of ``values`` is certainly below ``bound``: both order
    statistics it interpolates between are below it (one count, no sort); False when it
    may not be (then compute it). ``sample``: the sample when already taken."""
    sample = _tail_sample(values) if sample is None else sample
    if sample.size < 2:
        return False
    below = int(np.floor((sample.size - 1) * (LOW_TAIL_PERCENT / 100.0)))
    return int(np.count_nonzero(sample < bound)) >= below + 2


def low_tail(values: np.ndarray, *, sample: np.ndarray | None = None) -> float:
    """The ``LOW_TAIL_PERCENT`` percentile of ``values`` (any shape; at most
    ``_TAIL_SAMPLES`` voxels sampled evenly, :func:`tail_step`), ``np.percentile``'s linear
    method. ``sample``: the sample when already taken.

    int16 values are counted instead of partitioned (one pass, no sort): the two order
    statistics the percentile interpolates between are read off the cumulative counts.
    """
    sample = _tail_sample(values) if sample is None else sample
    if sample.dtype != np.int16 or sample.size < 2:
        return float(np.percentile(sample, LOW_TAIL_PERCENT))
    q = LOW_TAIL_PERCENT / 100.0
    rank = (sample.size - 1) * q  # NumPy's virtual index (linear method)
    below = min(int(np.floor(rank)), sample.size - 2)
    cum = np.cumsum(np.bincount(sample.view(np.uint16) ^ 0x8000, minlength=1 << 16))
    a, b = (float(v) - 0x8000 for v in np.searchsorted(cum, [below + 1, below + 2]))
    t = rank - below
    return b - (b - a) * (1.0 - t) if t >= 0.5 else a + (b - a) * t
