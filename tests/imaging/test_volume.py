"""CTVolume: geometry helpers and trilinear sampling, checked against analytic fields."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from imaging import CTVolume, ImagingInputError, SeriesInfo
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
