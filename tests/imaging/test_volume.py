"""CTVolume: geometry helpers and trilinear sampling, checked against analytic fields."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from ctdrill.imaging import CTVolume, ImagingInputError, SeriesInfo, load_series
from tests.conftest import ASSETS
from tests.imaging.factory import affine, linear_hu, rotation, volume

SHAPE = (6, 9, 11)  # slices, rows, cols
ROT = rotation(25.0, -10.0, 40.0)
AFF = affine((0.4, 0.7, 1.3), rot=ROT, origin_lps=(12.0, -8.0, 33.0), tilt_deg=12.0)


def _lps(ijk: np.ndarray) -> np.ndarray:
    return np.asarray(ijk @ AFF[:3, :3].T + AFF[:3, 3])


def _linear(ijk: np.ndarray) -> np.ndarray:
    return np.asarray(3 * ijk[..., 0] + 7 * ijk[..., 1] + 50 * ijk[..., 2] - 400.0)


def test_dims_spacing_and_positions() -> None:
    v = volume(linear_hu(SHAPE), AFF)
    assert v.dims == (11, 9, 6)
    expected_k = 1.3 / np.cos(np.radians(12.0))
    np.testing.assert_allclose(v.spacing_mm, (0.4, 0.7, expected_k), rtol=1e-12)
    # Slice positions along the normal step by exactly 1.3 mm despite the shear.
    np.testing.assert_allclose(np.diff(v.slice_positions_mm), 1.3, rtol=1e-12)
    assert v.is_volume and v.uniform_slices()


def test_index_lps_round_trip() -> None:
    v = volume(linear_hu(SHAPE), AFF)
    ijk = np.random.default_rng(1).uniform(-2, 12, size=(50, 3))
    np.testing.assert_allclose(v.index_to_lps(ijk), _lps(ijk), atol=1e-12)
    np.testing.assert_allclose(v.lps_to_index(v.index_to_lps(ijk)), ijk, atol=1e-10)


def test_voxel_centres_return_stored_values() -> None:
    hu = linear_hu(SHAPE)
    v = volume(hu, AFF)
    k, j, i = np.indices(SHAPE)
    ijk = np.stack([i, j, k], axis=-1).astype(float)
    np.testing.assert_allclose(v.sample(_lps(ijk)), hu.astype(float), atol=1e-9)
    np.testing.assert_array_equal(v.sample(_lps(ijk), order=0), hu.astype(float))


@given(
    st.lists(
        st.tuples(
            st.floats(0, SHAPE[2] - 1), st.floats(0, SHAPE[1] - 1), st.floats(0, SHAPE[0] - 1)
        ),
        min_size=1,
        max_size=20,
    )
)
def test_trilinear_reproduces_a_linear_field_exactly(
    points: list[tuple[float, float, float]],
) -> None:
    v = volume(linear_hu(SHAPE), AFF)
    ijk = np.array(points, dtype=float)
    got = v.sample(_lps(ijk))
    np.testing.assert_allclose(got, _linear(ijk), atol=1e-8)


def test_batch_shape_is_kept() -> None:
    v = volume(linear_hu(SHAPE), AFF)
    ijk = np.random.default_rng(2).uniform(0, 5, size=(4, 7, 3))
    out = v.sample(_lps(ijk))
    assert out.shape == (4, 7) and out.dtype == np.float64
    np.testing.assert_allclose(out, _linear(ijk), atol=1e-8)


def test_outside_points_and_non_finite_points_get_outside_hu() -> None:
    v = volume(linear_hu(SHAPE), AFF)
    ijk = np.array(
        [
            [-1e-3, 2, 2],
            [SHAPE[2] - 1 + 1e-3, 2, 2],
            [3, SHAPE[1] - 0.5, 6.0],
            [3, 2, -0.2],
            [1e9, 0, 0],
        ]
    )
    pts = np.vstack([_lps(ijk), [[np.nan, 0, 0], [np.inf, 1, 1]]])
    got = v.sample(pts, outside_hu=-1234.5)
    np.testing.assert_array_equal(got, np.full(7, -1234.5))
    assert not v.inside(pts).any()
    # The hull boundary itself is inside (the last voxel centre).
    edge = _lps(np.array([[SHAPE[2] - 1, SHAPE[1] - 1, SHAPE[0] - 1]], dtype=float))
    np.testing.assert_allclose(v.sample(edge), _linear(np.array([[10, 8, 5]])), atol=1e-9)


def test_padding_is_substituted_by_outside_hu_and_never_bleeds() -> None:
    hu = np.full((2, 4, 4), 100, dtype=np.int16)
    hu[:, :, 2:] = -3024  # the stored padding value after rescale
    valid = np.ones(hu.shape, dtype=bool)
    valid[:, :, 2:] = False
    v = volume(hu, affine((1.0, 1.0, 1.0)), valid)
    ijk = np.array([[0.0, 1, 0], [1.0, 1, 0], [1.5, 1, 0], [2.0, 1, 0], [3.0, 1, 1]])
    pts = v.index_to_lps(ijk)
    got = v.sample(pts, outside_hu=-1000.0)
    np.testing.assert_allclose(got, [100.0, 100.0, -450.0, -1000.0, -1000.0])
    assert got.min() >= -1000.0  # -3024 never reaches a sample
    np.testing.assert_array_equal(v.inside(pts), [True, True, False, False, False])
    got0 = v.sample(pts, outside_hu=-500.0, order=0)
    np.testing.assert_allclose(got0, [100.0, 100.0, 100.0, -500.0, -500.0])


def test_single_slice_volume_samples_its_plane_only() -> None:
    hu = linear_hu((1, 5, 5))
    v = volume(hu, affine((1.0, 1.0, 2.0)))
    assert not v.is_volume
    on = v.index_to_lps(np.array([[1.5, 2.25, 0.0]]))
    off = v.index_to_lps(np.array([[1.5, 2.25, 0.1]]))
    np.testing.assert_allclose(v.sample(on), _linear(np.array([[1.5, 2.25, 0.0]])))
    assert v.sample(off)[0] == -1000.0


def test_arrays_are_read_only() -> None:
    v = volume(linear_hu(SHAPE), AFF)
    with pytest.raises(ValueError):
        v.hu[0, 0, 0] = 1
    with pytest.raises(ValueError):
        v.affine_lps[0, 0] = 1.0


@pytest.mark.parametrize(
    ("hu", "aff", "match"),
    [
        (np.zeros((4, 4)), np.eye(4), "slices, rows, cols"),
        (np.zeros((2, 3, 4)), np.eye(3), r"\(4, 4\)"),
        (np.zeros((2, 3, 4)), np.diag([1.0, 1.0, 0.0, 1.0]), "singular"),
    ],
)
def test_bad_construction_is_refused(hu: np.ndarray, aff: np.ndarray, match: str) -> None:
    with pytest.raises(ImagingInputError, match=match):
        CTVolume(hu=hu, affine_lps=aff, valid=None, info=SeriesInfo(series_uid="1"))


def test_true_slice_positions_are_kept_and_checked() -> None:
    pos = np.array([0.0, 1.0, 2.0, 3.5])
    v = CTVolume(
        hu=np.zeros((4, 2, 2), np.int16),
        affine_lps=np.eye(4),
        valid=None,
        info=SeriesInfo(series_uid="1"),
        slice_positions_mm=pos,
    )
    np.testing.assert_array_equal(v.slice_positions_mm, pos)
    assert not v.uniform_slices()
    with pytest.raises(ImagingInputError, match="slice_positions_mm"):
        CTVolume(
            hu=np.zeros((4, 2, 2), np.int16),
            affine_lps=np.eye(4),
            valid=None,
            info=SeriesInfo(series_uid="1"),
            slice_positions_mm=pos[:3],
        )


# ---------------------------------------------------------------- against a slow reference
def slow_trilinear(
    vol: CTVolume, points_lps: np.ndarray, *, outside_hu: float = -1000.0
) -> tuple[np.ndarray, np.ndarray]:
    """Reference trilinear HU and inside flags, corner by corner (no shared code with CTVolume).

    Returns (N,) HU and (N,) bool "support entirely on valid voxels inside the hull".
    """
    pts = np.asarray(points_lps, dtype=np.float64).reshape(-1, 3)
    inv = np.linalg.inv(np.asarray(vol.affine_lps))
    with np.errstate(invalid="ignore", over="ignore"):
        ijk = (np.c_[pts, np.ones(len(pts))] @ inv.T)[:, :3]
    n_s, n_r, n_c = vol.hu.shape
    size = np.array([n_c, n_r, n_s], dtype=np.float64)
    with np.errstate(invalid="ignore"):
        hull = np.all((ijk >= -1e-6) & (ijk <= size - 1 + 1e-6), axis=1)
    ijk = np.where(hull[:, None], np.clip(ijk, 0.0, size - 1), 0.0)
    lo = np.minimum(np.floor(ijk), np.maximum(size - 2, 0)).astype(int)
    frac = ijk - lo
    hu = np.asarray(vol.hu, dtype=np.float64)
    valid = np.ones(hu.shape, bool) if vol.valid is None else np.asarray(vol.valid)
    total = np.zeros(len(pts))
    all_valid = hull.copy()
    for bk in (0, 1):
        for bj in (0, 1):
            for bi in (0, 1):
                i = np.minimum(lo[:, 0] + bi, n_c - 1)
                j = np.minimum(lo[:, 1] + bj, n_r - 1)
                k = np.minimum(lo[:, 2] + bk, n_s - 1)
                w = (
                    (frac[:, 0] if bi else 1 - frac[:, 0])
                    * (frac[:, 1] if bj else 1 - frac[:, 1])
                    * (frac[:, 2] if bk else 1 - frac[:, 2])
                )
                ok = valid[k, j, i]
                total += w * np.where(ok, hu[k, j, i], outside_hu)
                all_valid &= ok | (w == 0.0)
    return np.where(hull, total, outside_hu), all_valid


def _probe_points(vol: CTVolume, n: int, seed: int) -> np.ndarray:
    """Points inside, on the hull faces, just beyond them, far away and non-finite, LPS mm."""
    rng = np.random.default_rng(seed)
    top = np.array(vol.dims, dtype=np.float64) - 1
    ijk = rng.uniform(-0.5, 1.5, size=(n, 3)) * top
    ijk[: n // 8, 0] = 0.0  # on a face
    ijk[n // 8 : n // 4, 1] = top[1]  # on the opposite face
    ijk[n // 4 : n // 4 + 5] = top + 1e-7  # the far corner, within the edge tolerance
    pts = vol.index_to_lps(ijk)
    far = np.array([[1e6, 0, 0], [0, -1e9, 3], [np.nan, 0, 0], [np.inf, 1, 2], [-np.inf] * 3])
    return np.concatenate([pts, far])


@pytest.mark.parametrize("dtype", [np.int16, np.float32])
@pytest.mark.parametrize("padded", [False, True])
def test_sample_and_inside_match_the_slow_reference(dtype: type, padded: bool) -> None:
    rng = np.random.default_rng(7)
    hu = rng.integers(-1000, 2500, size=SHAPE).astype(dtype)
    valid = rng.random(SHAPE) > 0.2 if padded else None
    v = volume(hu, AFF, valid)
    assert (v.valid is None) is (not padded)
    pts = _probe_points(v, 3000, seed=3)
    for outside_hu in (-1000.0, 123.5):
        ref, ref_inside = slow_trilinear(v, pts, outside_hu=outside_hu)
        got = v.sample(pts, outside_hu=outside_hu)
        assert np.all(np.isfinite(got))
        np.testing.assert_allclose(got, ref, rtol=0, atol=1e-3)
        np.testing.assert_array_equal(v.inside(pts), ref_inside)
    # The far and non-finite points are outside.
    assert np.all(v.sample(pts[-5:], outside_hu=-777.0) == -777.0)


def test_sample_matches_the_slow_reference_on_the_demo_ct() -> None:
    v = load_series(ASSETS / "demo" / "ct")
    pts = _probe_points(v, 4000, seed=11)
    ref, ref_inside = slow_trilinear(v, pts)
    np.testing.assert_allclose(v.sample(pts), ref, rtol=0, atol=1e-3)
    np.testing.assert_array_equal(v.inside(pts), ref_inside)


def test_sample_on_single_voxel_axes_matches_the_slow_reference() -> None:
    hu = np.arange(7, dtype=np.int16).reshape(1, 1, 7) * 10
    v = volume(hu, affine((0.5, 0.5, 1.0)))
    ijk = np.c_[np.linspace(-0.5, 6.5, 57), np.zeros(57), np.zeros(57)]
    ijk[::4, 1] = 1e-7  # within the edge tolerance of the single row
    ijk[1::9, 2] = 0.01  # beyond it: outside
    pts = v.index_to_lps(ijk)
    ref, _ = slow_trilinear(v, pts)
    np.testing.assert_allclose(v.sample(pts), ref, rtol=0, atol=1e-3)
