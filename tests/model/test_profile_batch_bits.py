"""The batched profile's NumPy path gives the compiled kernel's bits (issue 37): a row's force
profile must not depend on whether its process loaded numba (a one-plan export that skips
numba, a batch worker, the window). Hypothesis drives both with adversarial ring samples: HU on
the gate's edges and on the ends of the calibration's C' range, far outside it, table nodes,
rows of different lengths, NaN samples and a subset of the rows."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ctdrill import jit
from ctdrill.hu import AIR_HU
from ctdrill.model.calibration import Calibration, load_calibration
from ctdrill.model.profile import build_profile
from ctdrill.model.profile_batch import PROFILE_KERNEL, ProfileBatch, build_profiles, law_tables

CALIBRATIONS = ("bone-illustrative", "bone-literature", "pine-wood-paper")


@pytest.fixture(scope="module", autouse=True)
def kernel() -> None:
    """The compiled kernel, as `make warmup` leaves it (compiled here when missing)."""
    jit.warm_up([PROFILE_KERNEL])


def _edges(cal: Calibration) -> list[float]:
    """HU values where the kernel's branches and tables change."""
    lo, hi = (float(v) for v in cal.c_prime_range)
    gate_lo = float(cal.gate_hu) - 0.5 * float(cal.gate_width_hu)
    gate_hi = gate_lo + float(cal.gate_width_hu)
    _, inv_step, coefs = law_tables(cal)
    nodes = [lo + AIR_HU + k / inv_step for k in (0, 1, coefs.shape[0] // 2, coefs.shape[0])]
    return [gate_lo, gate_hi, lo + AIR_HU, hi + AIR_HU, AIR_HU, -3000.0, 4000.0, *nodes]


@st.composite
def cases(draw: st.DrawFn) -> tuple[Calibration, np.ndarray, np.ndarray, np.ndarray]:
    cal = load_calibration(draw(st.sampled_from(CALIBRATIONS)))
    n = draw(st.integers(1, 4))
    d = draw(st.integers(1, 12))
    r = draw(st.integers(1, 5))
    a = draw(st.integers(1, 9))
    edges = _edges(cal)
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    hu = rng.uniform(-1500.0, 3500.0, (n, d, r, a))
    pick = rng.random(hu.shape) < draw(st.floats(0.0, 1.0))
    hu[pick] = rng.choice(edges, int(pick.sum()))
    nudge = rng.random(hu.shape) < 0.2  # one float32 step either side of an edge
    hu[nudge] = np.nextafter(hu[nudge].astype(np.float32), np.float32(rng.choice([-1e9, 1e9])))
    hu[rng.random(hu.shape) < 0.05] = np.nan  # a sample the sampler could not take
    n_depths = rng.integers(1, d + 1, n)
    rows = np.flatnonzero(rng.random(n) < 0.8)
    return cal, hu.astype(np.float32), n_depths.astype(np.int64), rows


def _run(cal: Calibration, hu: np.ndarray, n_depths: np.ndarray, rows: np.ndarray) -> ProfileBatch:
    n, d, r, _ = hu.shape
    depth = np.tile(np.arange(d) * 0.1, (n, 1))
    ring_w = np.full(r, 1.0 / r)
    alt_w = np.arange(1.0, r + 1.0) / (r * (r + 1) / 2)
    return build_profiles(
        hu, depth, n_depths, ring_w, cal, blades=3, rpm=800.0, alt_weights=alt_w, rows=rows
    )


@settings(max_examples=150, deadline=None)
@given(cases())
def test_numpy_path_gives_the_kernels_bits(
    case: tuple[Calibration, np.ndarray, np.ndarray, np.ndarray],
) -> None:
    cal, hu, n_depths, rows = case
    assert PROFILE_KERNEL.ready()
    got = _run(cal, hu, n_depths, rows)
    with jit.switched_off([PROFILE_KERNEL]):
        want = _run(cal, hu, n_depths, rows)
    for name in ("s0_n", "sk_n", "s_t", "hu_mean", "hu_mean_alt", "n_clipped", "n_samples"):
        a, b = getattr(got, name), getattr(want, name)
        assert a.dtype == b.dtype and a.shape == b.shape, name
        # bit for bit, NaN where nothing was computed
        assert np.array_equal(a.view(np.uint64) if a.dtype == np.float64 else a,
                              b.view(np.uint64) if b.dtype == np.float64 else b), name  # fmt: skip


def test_both_paths_are_the_reference_profile() -> None:
    """Both equal build_profile (the lip integral with the laws themselves, NumPy's own sums)
    to the tables' accuracy."""
    cal = load_calibration("bone-literature")
    rng = np.random.default_rng(5)
    hu = rng.uniform(-1200.0, 2500.0, (2, 30, 4, 16)).astype(np.float32)
    n_depths = np.array([30, 17])
    for switched in (False, True):
        with jit.switched_off([PROFILE_KERNEL] if switched else []):
            got = _run(cal, hu, n_depths, np.arange(2))
        for i in range(2):
            m = int(n_depths[i])
            ref = build_profile(
                hu[i, :m], np.full(4, 0.25), np.arange(m) * 0.1, cal, blades=3, rpm=800.0
            )
            np.testing.assert_allclose(got.s0_n[i, :m], ref.s0_n, rtol=1e-10)
            np.testing.assert_allclose(got.sk_n[i, :, :m], ref.sk_n, rtol=1e-10)
            np.testing.assert_allclose(got.s_t[i, :m], ref.s_t, rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(got.hu_mean[i, :m], ref.hu_mean, rtol=1e-12)
            assert got.n_clipped[i] == ref.n_clipped
