"""The compiled envelope rays started and finished: the kernel
(:mod:`~ctdrill.imaging.sampling.envelope_kernel`) runs on the worker threads and the calling
thread, each claiming rays (:func:`ctdrill.claims.start_claimed`), so a caller can start them, do
other work, and finish them; and the full march the tests and benchmarks hold it to.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator

import numpy as np

from ctdrill.claims import start_claimed
from ctdrill.imaging.misch import BONE_HU
from ctdrill.imaging.sampling.envelope_kernel import ENVELOPE_KERNEL
from ctdrill.imaging.sampling.hu_blocks import block_classes, hu_bound
from ctdrill.imaging.sampling.kernel_args import fits, volume_args
from ctdrill.imaging.teeth import TOOTH_HU
from ctdrill.imaging.volume import CTVolume

#: Rays below twice this are all marched by one thread (waking threads costs more).
_MIN_SPAN = 64

#: Set within :func:`full_march`.
_FULL_MARCH = [False]


@contextlib.contextmanager
def full_march() -> Iterator[None]:
    """Within the block every ray reads every sample, no block stepped over (the walls'
    reference march, timed beside the skipping one by ``bench/bench_shells.py``)."""
    saved = _FULL_MARCH[0]
    _FULL_MARCH[0] = True
    try:
        yield
    finally:
        _FULL_MARCH[0] = saved


def kernel_fits(volume: CTVolume) -> bool:
    """The compiled kernel can read ``volume`` (no padding, int16 or float32 voxels) and is
    loaded from the cache."""
    return fits(volume) and ENVELOPE_KERNEL.ready()


def envelope_rays(
    volume: CTVolume,
    origins_lps: np.ndarray,
    dirs_lps: np.ndarray,
    *,
    step: float,
    n_steps: int,
    gap_steps: int,
    tooth_edge: int,
    max_wall_mm: float,
    reach_mm: float,
    air_hu: float,
    bisect_tol_mm: float,
    skip_blocks: bool | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(wall, unknown, open)`` (N,) of each ray by the compiled kernel (only when
    :func:`kernel_fits`); the arguments are those of ``envelope_walls`` and its constants.
    ``skip_blocks`` False: every sample read, no block stepped over (the full march the
    tests and the benchmark hold the skipping one to: the same answers); None: as
    :func:`full_march` says (True outside it)."""
    return start_envelope_rays(
        volume,
        origins_lps,
        dirs_lps,
        step=step,
        n_steps=n_steps,
        gap_steps=gap_steps,
        tooth_edge=tooth_edge,
        max_wall_mm=max_wall_mm,
        reach_mm=reach_mm,
        air_hu=air_hu,
        bisect_tol_mm=bisect_tol_mm,
        skip_blocks=skip_blocks,
    )()


def start_envelope_rays(
    volume: CTVolume,
    origins_lps: np.ndarray,
    dirs_lps: np.ndarray,
    *,
    step: float,
    n_steps: int,
    gap_steps: int,
    tooth_edge: int,
    max_wall_mm: float,
    reach_mm: float,
    air_hu: float,
    bisect_tol_mm: float,
    skip_blocks: bool | None = None,
) -> Callable[[], tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """:func:`envelope_rays` started on the worker threads: returns at once a function that
    lends the calling thread to the rays still free, waits for the rest and returns
    ``(wall, unknown, open)`` (:func:`ctdrill.claims.start_claimed`)."""
    if skip_blocks is None:
        skip_blocks = not _FULL_MARCH[0]
    n = len(origins_lps)
    wall = np.zeros(n)
    unknown = np.zeros(n, dtype=np.bool_)
    open_ = np.zeros(n, dtype=np.bool_)
    if n == 0:
        return lambda: (wall, unknown, open_)
    k_cap = int(np.searchsorted(np.arange(n_steps) * step, max_wall_mm - 1e-12))
    # a sample within this of a threshold is read with the exact point's arithmetic: far
    # beyond the ~1e-12 voxel rounding of the extrapolated index times the steepest edge
    eps_hu = 1e-3 + 1e-9 * hu_bound(volume)
    params = np.array(
        [step, max_wall_mm, reach_mm, BONE_HU, TOOTH_HU, air_hu, bisect_tol_mm, eps_hu],
        dtype=np.float64,
    )
    ints = np.array([n_steps, gap_steps, tooth_edge, k_cap], dtype=np.int64)
    job = start_claimed(
        ENVELOPE_KERNEL,
        n,
        *volume_args(volume),
        (
            block_classes(volume, air_hu, BONE_HU, TOOTH_HU)
            if skip_blocks
            else np.zeros((0, 0, 0), dtype=np.int8)
        ),
        np.ascontiguousarray(origins_lps, dtype=np.float64),
        np.ascontiguousarray(dirs_lps, dtype=np.float64),
        params,
        ints,
        wall,
        unknown,
        open_,
        min_rows=2 * _MIN_SPAN,
    )

    def finish() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        job.join()
        return wall, unknown, open_

    return finish
