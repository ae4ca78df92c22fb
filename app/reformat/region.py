"""The panorama's default rows: the arch region, not the scan's whole height.

A head CT is often 130 mm tall or more; a panorama of all of it leaves the jaw, its implants and
canal a thin strip at one edge. The window and ``ctdrill report`` show :data:`PANORAMA_HEIGHT_MM`
around the jaw instead (``ctdrill panorama`` keeps the whole height unless ``--height-mm``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.sampling.reformat_grid import volume_z_range_mm
from ctdrill.imaging.volume import CTVolume

#: The panorama's default height, mm: the arch region (a jaw's bone, its implants and canal,
#: the teeth above), not the scan's whole height.
PANORAMA_HEIGHT_MM = 60.0
#: How far the default panorama's middle lies from the arch toward the implants' apices
#: (into the jaw's bone), mm: it shows 45 mm of the bone side and 15 mm of the teeth side.
PANORAMA_SHIFT_MM = 15.0


def arch_region(
    volume: CTVolume, arch_lps: np.ndarray, plans: Sequence[Plan]
) -> tuple[float | None, float | None]:
    """The panorama's default rows, (height, middle z) in mm: :data:`PANORAMA_HEIGHT_MM` with
    its middle :data:`PANORAMA_SHIFT_MM` from the arch's mean height toward the implants'
    apices (down without trajectories: a mandible), inside the volume's height; (None, None)
    when the volume is not taller (its whole height then)."""
    z_lo, z_hi = volume_z_range_mm(volume)
    if z_hi - z_lo <= PANORAMA_HEIGHT_MM:
        return None, None
    down = sum(float(p.target_lps[2] - p.entry_lps[2]) for p in plans)
    sign = 1.0 if down > 0.0 else -1.0
    half = 0.5 * PANORAMA_HEIGHT_MM
    mid = float(np.mean(np.asarray(arch_lps)[:, 2])) + sign * PANORAMA_SHIFT_MM
    mid = float(np.clip(mid, z_lo + half, z_hi - half))
    return PANORAMA_HEIGHT_MM, mid
