"""Explicit resampling of an irregular stack (gaps, variable steps) onto uniform slices.

The loader never interpolates on its own: a stack with ``slice_gap`` or ``nonuniform_spacing``
keeps its true ``slice_positions_mm``. When the caller decides to use it as a regular volume,
this function interpolates linearly between the two neighbouring true slices, along the stack's
own k direction (the affine's k column, sheared for a gantry tilt), and says so in
``info.resampled``.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.stack import median
from ctdrill.imaging.volume import CTVolume
from ctdrill.warning_codes import slice_spacing_codes


def resample_uniform_slices(volume: CTVolume, *, step_mm: float | None = None) -> CTVolume:
    """A copy of ``volume`` on uniform slice positions.

    Parameters
    ----------
    volume : CTVolume
        Any stack with at least two slices.
    step_mm : float | None
        Slice step along the normal, mm; default the median true step.

    Returns
    -------
    CTVolume
        float32 HU linearly interpolated between the bracketing true slices (a voxel is valid
        where both contributing voxels with non-zero weight are valid); the same origin and
        k direction; positions ``p0 + k * step`` up to the last true slice; ``slice_gap`` and
        ``nonuniform_spacing`` replaced by ``info.resampled`` True.
    """
    pos = np.asarray(volume.slice_positions_mm, dtype=np.float64)
    if pos.size < 2:
        raise ImagingInputError("resample_uniform_slices: one slice cannot be resampled")
    steps = np.diff(pos)
    step = median(steps) if step_mm is None else float(step_mm)
    if not np.isfinite(step) or step <= 0:
        raise ImagingInputError(f"step_mm: {step_mm} must be a positive number of mm")
    n_new = int(np.floor((pos[-1] - pos[0]) / step + 1e-6)) + 1
    bytes_needed = n_new * volume.hu[0].size * 4
    if bytes_needed > 2 * 1024**3:
        raise ImagingInputError(
            f"step_mm: {step:g} mm gives {n_new} slices ({bytes_needed / 2**20:.0f} MiB); "
            "choose a larger step"
        )
    target = pos[0] + step * np.arange(n_new)
    upper = np.clip(np.searchsorted(pos, target, side="right"), 1, pos.size - 1)
    lower = upper - 1
    weight = np.clip((target - pos[lower]) / (pos[upper] - pos[lower]), 0.0, 1.0)
    hu = np.empty((n_new, *volume.hu.shape[1:]), dtype=np.float32)
    valid = None if volume.valid is None else np.empty(hu.shape, dtype=bool)
    tmp = np.empty(hu.shape[1:], dtype=np.float32)
    for k in range(n_new):
        a, b, w = int(lower[k]), int(upper[k]), float(weight[k])
        np.multiply(volume.hu[a], np.float32(1.0 - w), out=hu[k])
        np.multiply(volume.hu[b], np.float32(w), out=tmp)
        hu[k] += tmp
        if valid is not None and volume.valid is not None:
            valid[k] = (volume.valid[a] | (w == 1.0)) & (volume.valid[b] | (w == 0.0))
    affine = np.array(volume.affine_lps)
    kcol = affine[:3, 2]
    normal = np.cross(affine[:3, 0], affine[:3, 1])
    normal /= np.linalg.norm(normal)
    affine[:3, 2] = kcol * (step / float(kcol @ normal))
    spacing = slice_spacing_codes()  # resolved by the uniform slices
    warnings = tuple(w for w in volume.warnings if w.code not in spacing)
    return CTVolume(
        hu=hu,
        affine_lps=affine,
        valid=valid,
        info=replace(volume.info, resampled=True),
        warnings=warnings,
        slice_positions_mm=target,
    )
