"""The compiled order-1 sampler gives scipy's ``map_coordinates`` bits, edges included."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy import ndimage

from ctdrill import jit
from ctdrill.imaging.dicom.series import load_series
from ctdrill.imaging.sampling import points_kernel
from ctdrill.imaging.sampling.points_kernel import (
    POINTS_KERNEL,
    sample_index_points,
    sample_index_points_numpy,
)

ASSETS = Path(__file__).resolve().parents[2] / "assets"


@pytest.fixture(scope="module", autouse=True)
def kernels() -> None:
    """The kernel as `make warmup` leaves it (compiled here when the cache is missing)."""
    jit.warm_up([POINTS_KERNEL])
    assert POINTS_KERNEL.ready()


def _points(shape: tuple[int, ...], n: int, rng: np.random.Generator) -> np.ndarray:
    """Index points over the hull and its 1e-6 voxel tolerance: random, whole numbers (the
    voxel centres and the far edge) and points just outside each face."""
    c = np.empty((3, n))
    for axis, size in enumerate(shape):
        c[axis] = rng.uniform(-1e-6, size - 1 + 1e-6, n)
    c[:, : n // 10] = np.round(c[:, : n // 10])
    for axis, size in enumerate(shape):
        lo = n // 10 + axis * (n // 20)
        c[axis, lo : lo + n // 40] = -1e-6
        c[axis, lo + n // 40 : lo + n // 20] = size - 1 + 1e-6
    return c


@pytest.mark.parametrize("dtype", [np.int16, np.float32])
def test_the_kernel_gives_map_coordinates_bits(dtype: type) -> None:
    rng = np.random.default_rng(7)
    vol = (rng.normal(size=(6, 9, 11)) * 900).astype(dtype)
    coords = _points(vol.shape, 150_000, rng)  # more than THREAD_POINTS: split in threads
    out = np.empty(coords.shape[1])
    assert sample_index_points(vol, coords, out)
    ref = np.empty_like(out)
    ndimage.map_coordinates(vol, coords, output=ref, order=1, mode="nearest", prefilter=False)
    np.testing.assert_array_equal(out, ref)


@pytest.mark.parametrize("dtype", [np.int16, np.float32])
def test_the_numpy_path_gives_map_coordinates_bits(
    dtype: type, monkeypatch: pytest.MonkeyPatch
) -> None:
    rng = np.random.default_rng(11)
    vol = (rng.normal(size=(5, 7, 4)) * 900).astype(dtype)
    coords = _points(vol.shape, 20_000, rng)
    monkeypatch.setattr(points_kernel, "NUMPY_BLOCK_POINTS", 3001)  # several blocks, one short
    out = np.empty(coords.shape[1])
    sample_index_points_numpy(vol, coords, out)
    ref = np.empty_like(out)
    ndimage.map_coordinates(vol, coords, output=ref, order=1, mode="nearest", prefilter=False)
    np.testing.assert_array_equal(out, ref)


def test_other_types_are_left_to_the_caller() -> None:
    coords = np.zeros((3, 4))
    out = np.full(4, 7.0)
    assert not sample_index_points(np.zeros((2, 2, 2), dtype=np.float64), coords, out)
    assert not sample_index_points(np.zeros((2, 2, 2), np.int16)[:, :, ::-1], coords, out)
    assert (out == 7.0).all()


def test_the_volume_samples_the_same_with_and_without_the_kernel() -> None:
    volume = load_series(ASSETS / "demo" / "ct")
    rng = np.random.default_rng(3)
    lo, hi = volume.index_to_lps(np.zeros(3)), volume.index_to_lps(np.array(volume.hu.shape[::-1]))
    pts = rng.uniform(np.minimum(lo, hi) - 2.0, np.maximum(lo, hi) + 2.0, size=(5000, 3))
    fast = volume.sample(pts)
    with jit.switched_off([POINTS_KERNEL]):
        slow = volume.sample(pts)
    np.testing.assert_array_equal(fast, slow)
