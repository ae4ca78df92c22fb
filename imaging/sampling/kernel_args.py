"""What a compiled kernel reading a CT through :func:`~ctdrill.imaging.sampling.trilinear.trilinear`
is passed for the volume, and whether it can read it (:func:`fits`)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ctdrill.imaging.volume import CTVolume


def volume_args(volume: CTVolume) -> tuple[Any, ...]:
    """The arguments :func:`trilinear` reads, in its order: voxels (int16 or float32),
    inverse affine (3, 3) and offset (3,), the index hull's top (3,), the nominal slice
    positions and whether they are remapped."""
    return (
        np.ascontiguousarray(volume.hu),
        np.ascontiguousarray(volume._inv_lin),
        np.ascontiguousarray(volume._inv_off),
        np.ascontiguousarray(volume._top),
        np.ascontiguousarray(volume._k_nominal, dtype=np.float64),
        bool(volume._remap_k),
    )


def fits(volume: CTVolume) -> bool:
    """A compiled kernel can read ``volume`` through :func:`trilinear`: no padding, int16 or
    float32 voxels."""
    return volume.valid is None and volume.hu.dtype in (np.int16, np.float32)
