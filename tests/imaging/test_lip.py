"""Lip-ring sampling: exact geometry, exact values on analytic volumes, outside counting."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from ctdrill.imaging import load_series
from ctdrill.imaging.plan.load import load_plan
from ctdrill.imaging.plan.types import DrillSpec
from ctdrill.imaging.sampling.lip import (
    LipInputError,
    axis_basis,
    lip_ring_points,
    ring_radii_mm,
    sample_lip_rings,
)
from ctdrill.imaging.volume import CTVolume, SeriesInfo
from tests.conftest import ASSETS
from tests.imaging.test_volume import slow_trilinear

finite = st.floats(min_value=-200.0, max_value=200.0, allow_nan=False)
point = st.tuples(finite, finite, finite).map(np.array)


def _volume(hu: np.ndarray, affine: np.ndarray, valid: np.ndarray | None = None) -> CTVolume:
    return CTVolume(hu=hu, affine_lps=affine, valid=valid, info=SeriesInfo(series_uid="1.2.3"))


def _rotated_affine(
    spacing: tuple[float, float, float], origin: tuple[float, float, float]
) -> np.ndarray:
    """An oblique, anisotropic affine: rotation about a skew axis times the spacings."""
    axis = np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0)
    ang = 0.4
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    rot = np.eye(3) + np.sin(ang) * k + (1 - np.cos(ang)) * (k @ k)
    a = np.eye(4)
    a[:3, :3] = rot * np.array(spacing)[None, :]
    a[:3, 3] = origin
    return a


@given(entry=point, target=point)
def test_axis_basis_is_orthonormal_and_right_handed(entry: np.ndarray, target: np.ndarray) -> None:
    if not np.linalg.norm(target - entry) > 1e-9:
        with pytest.raises(LipInputError):
            axis_basis(entry, target)
        return
    basis = axis_basis(entry, target)
    np.testing.assert_allclose(basis @ basis.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(basis) == pytest.approx(1.0)
    d = (target - entry) / np.linalg.norm(target - entry)
    np.testing.assert_allclose(basis[0], d, atol=1e-12)


def test_axis_basis_for_a_straight_down_drill() -> None:
    basis = axis_basis(np.array([1.0, 2.0, 3.0]), np.array([1.0, 2.0, -7.0]))
    np.testing.assert_array_equal(basis, [[0, 0, -1], [1, 0, 0], [0, -1, 0]])


def test_ring_radii_are_bin_midpoints() -> None:
    np.testing.assert_allclose(ring_radii_mm(2.0, 4), [0.125, 0.375, 0.625, 0.875])
    np.testing.assert_allclose(ring_radii_mm(3.0, 1), [0.75])


@given(
    entry=point,
    target=point,
    diameter=st.floats(0.5, 6.0),
    tip=st.floats(0.0, 2.0),
    n_rings=st.integers(1, 9),
    n_angles=st.integers(1, 17),
)
def test_ring_points_sit_at_radius_r_and_depth_xi(
    entry: np.ndarray,
    target: np.ndarray,
    diameter: float,
    tip: float,
    n_rings: int,
    n_angles: int,
) -> None:
    if np.linalg.norm(target - entry) < 1e-3:
        return
    depth = np.array([-1.0, 0.0, 0.3, 7.25])
    pts = lip_ring_points(
        entry,
        target,
        depth,
        drill=DrillSpec(diameter_mm=diameter, tip_length_mm=tip),
        n_rings=n_rings,
        n_angles=n_angles,
    )
    assert pts.shape == (4, n_rings, n_angles, 3)
    axis = axis_basis(entry, target)[0]
    rel = pts - entry
    along = rel @ axis
    radial = np.linalg.norm(rel - along[..., None] * axis, axis=-1)
    r = (np.arange(n_rings) + 0.5) * diameter / 2.0 / n_rings
    xi = depth[:, None] - tip * r[None, :] / (diameter / 2.0)
    np.testing.assert_allclose(along, np.broadcast_to(xi[:, :, None], along.shape), atol=1e-9)
    np.testing.assert_allclose(radial, np.broadcast_to(r[None, :, None], radial.shape), atol=1e-9)


def test_ring_angles_are_equally_spaced_from_e1() -> None:
    entry, target = np.zeros(3), np.array([0.0, 0.0, -10.0])
    pts = lip_ring_points(
        entry,
        target,
        np.array([2.0]),
        drill=DrillSpec(diameter_mm=2.0, tip_length_mm=0.0),
        n_rings=1,
        n_angles=8,
    )
    _, e1, e2 = axis_basis(entry, target)
    ring = pts[0, 0] - np.array([0.0, 0.0, -2.0])
    ang = np.arctan2(ring @ e2, ring @ e1)
    np.testing.assert_allclose(np.mod(ang, 2 * np.pi), np.arange(8) * np.pi / 4, atol=1e-12)


def test_linear_field_is_sampled_exactly_on_an_oblique_grid() -> None:
    affine = _rotated_affine((0.3, 0.45, 0.6), (-5.0, 3.0, 2.0))
    n_s, n_r, n_c = 40, 36, 44
    k, j, i = np.meshgrid(np.arange(n_s), np.arange(n_r), np.arange(n_c), indexing="ij")
    lps = np.stack([i, j, k], -1) @ affine[:3, :3].T + affine[:3, 3]
    grad = np.array([3.0, -2.0, 5.0])
    hu = (100.0 + lps @ grad).astype(np.float32)
    vol = _volume(hu, affine)
    centre = affine[:3, :3] @ np.array([n_c, n_r, n_s]) / 2.0 + affine[:3, 3]
    entry = centre + np.array([1.0, -2.0, 3.0])
    target = centre - np.array([0.5, -1.0, 1.5])
    depth = np.linspace(0.0, 6.0, 31)
    lip = sample_lip_rings(
        vol,
        entry,
        target,
        depth,
        drill=DrillSpec(diameter_mm=2.2, tip_length_mm=0.7),
        n_rings=5,
        n_angles=9,
    )
    pts = lip_ring_points(
        entry,
        target,
        depth,
        drill=DrillSpec(diameter_mm=2.2, tip_length_mm=0.7),
        n_rings=5,
        n_angles=9,
    )
    assert lip.hu.dtype == np.float32 and lip.hu.shape == (31, 5, 9)
    np.testing.assert_allclose(lip.hu, 100.0 + pts @ grad, atol=0.02)
    axis = (target - entry) / np.linalg.norm(target - entry)
    np.testing.assert_allclose(
        lip.axis_hu, 100.0 + (entry + depth[:, None] * axis) @ grad, atol=0.02
    )
    np.testing.assert_array_equal(lip.outside, np.zeros(31))
    np.testing.assert_allclose(lip.ring_weights, np.full(5, 0.2))
    np.testing.assert_allclose(lip.radii_mm, ring_radii_mm(2.2, 5))
    # The lip mean of a linear field is the field at the weighted ring centres.
    xi_mean = depth - 0.7 * float(np.mean(lip.radii_mm)) / 1.1
    np.testing.assert_allclose(
        lip.lip_mean_hu, 100.0 + (entry + xi_mean[:, None] * axis) @ grad, atol=0.02
    )


def _slab_volume(spacing: float = 0.25) -> tuple[CTVolume, float]:
    """Bone (1000 HU) below z = z_top, air above; returns the volume and z_top (LPS mm).

    The step lies halfway between two voxel-centre planes, where trilinear crosses 0 HU.
    """
    n = 64
    affine = np.diag([spacing, spacing, spacing, 1.0])
    affine[:3, 3] = [-8.0, -8.0, -8.0]
    z = affine[2, 3] + spacing * np.arange(n)
    k_top = 40
    hu = np.where(z <= z[k_top], 1000, -1000).astype(np.int16)
    vol = _volume(np.broadcast_to(hu[:, None, None], (n, n, n)).copy(), affine)
    return vol, float(z[k_top] + spacing / 2.0)


@pytest.mark.parametrize("n_rings", [1, 4, 7])
def test_slab_fraction_equals_the_analytic_ring_fraction(n_rings: int) -> None:
    vol, z_top = _slab_volume()
    entry = np.array([0.1, -0.2, z_top + 1.0])
    target = entry - np.array([0.0, 0.0, 10.0])
    radius, tip = 1.0, 0.6
    depth = np.linspace(0.0, 2.5, 101) + 0.0037  # never exactly on the step plane
    lip = sample_lip_rings(
        vol,
        entry,
        target,
        depth,
        drill=DrillSpec(diameter_mm=2 * radius, tip_length_mm=tip),
        n_rings=n_rings,
        n_angles=6,
    )
    inside_frac = (lip.hu > 0.0).mean(axis=(1, 2))
    # Ring i is in bone when its depth xi_i = x - tip r_i / R passes the step at depth 1.0.
    xi = depth[:, None] - tip * lip.radii_mm[None, :] / radius
    expected = (xi > 1.0).mean(axis=1)
    np.testing.assert_array_equal(inside_frac, expected)
    # And the midpoint rule is within half a bin of the continuous contact fraction (Eq. 2).
    continuous = np.clip((depth - 1.0) / tip, 0.0, 1.0)
    assert np.max(np.abs(inside_frac - continuous)) <= 0.5 / n_rings + 1e-12


def test_outside_counts_samples_beyond_the_grid() -> None:
    vol, _ = _slab_volume(spacing=0.25)  # grid z from -8.0 to +7.75
    entry = np.array([0.0, 0.0, 6.0])
    target = np.array([0.0, 0.0, 9.0])  # drilling up and out of the grid
    depth = np.array([0.5, 1.7, 1.76, 2.0, 3.0])
    lip = sample_lip_rings(
        vol,
        entry,
        target,
        depth,
        drill=DrillSpec(diameter_mm=2.0, tip_length_mm=0.6),
        n_rings=4,
        n_angles=5,
        outside_hu=-1234.0,
    )
    xi = depth[:, None] - 0.6 * lip.radii_mm[None, :]
    expected = 5 * (6.0 + xi > 7.75).sum(axis=1)
    np.testing.assert_array_equal(lip.outside, expected)
    assert np.all(lip.hu[xi + 6.0 > 7.75] == -1234.0)
    np.testing.assert_array_equal(lip.axis_hu > -1234.0, 6.0 + depth <= 7.75)


def test_padding_is_counted_and_given_outside_hu() -> None:
    vol, _ = _slab_volume()
    valid = np.ones(vol.hu.shape, dtype=bool)
    valid[:, :, :32] = False  # x < 0 is padding (voxel centres x = -8 + 0.25 i)
    padded = _volume(np.array(vol.hu), vol.affine_lps, valid)
    entry = np.array([2.0, 0.0, 0.0])
    target = np.array([2.0, 0.0, -5.0])
    lip = sample_lip_rings(
        padded,
        entry,
        target,
        np.array([1.0]),
        drill=DrillSpec(diameter_mm=2.0, tip_length_mm=0.0),
        n_rings=2,
        n_angles=4,
    )
    assert lip.outside.tolist() == [0]
    entry = np.array([0.6, 0.0, 0.0])
    target = np.array([0.6, 0.0, -5.0])
    lip = sample_lip_rings(
        padded,
        entry,
        target,
        np.array([1.0]),
        drill=DrillSpec(diameter_mm=2.0, tip_length_mm=0.0),
        n_rings=2,
        n_angles=4,
    )
    # Straight down, e1 = +x: angle 2 (-x) of ring r = 0.75 reaches x = -0.15 (padding); the
    # r = 0.25 ring stays at x >= 0.35, whose support x in [0.25, 0.5] is valid.
    pts = lip_ring_points(
        entry,
        target,
        np.array([1.0]),
        drill=DrillSpec(diameter_mm=2.0, tip_length_mm=0.0),
        n_rings=2,
        n_angles=4,
    )
    assert int(lip.outside[0]) == int((pts[..., 0] < 0.0).sum()) == 1
    assert lip.hu[0, 1, 2] > -1000.0 and lip.hu[0, 1, 2] < 1000.0  # blends towards outside_hu


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"diameter_mm": 0.0}, "diameter_mm"),
        ({"tip_length_mm": -0.1}, "tip_length_mm"),
        ({"n_rings": 0}, "n_rings"),
        ({"n_angles": 2.5}, "n_angles"),
        ({"outside_hu": float("nan")}, "outside_hu"),
    ],
)
def test_bad_drill_geometry_names_the_field(kwargs: dict[str, float], field: str) -> None:
    vol, _ = _slab_volume()
    geometry = {k: kwargs.pop(k) for k in ("diameter_mm", "tip_length_mm") if k in kwargs}
    drill = DrillSpec(**{"diameter_mm": 2.0, "tip_length_mm": 0.6, **geometry})
    with pytest.raises(LipInputError, match=field):
        sample_lip_rings(vol, np.zeros(3), np.array([0, 0, -1.0]), np.array([0.0]), drill, **kwargs)  # type: ignore[arg-type]


def test_same_entry_and_target_is_bad_input() -> None:
    vol, _ = _slab_volume()
    with pytest.raises(LipInputError, match="entry and target"):
        sample_lip_rings(
            vol,
            np.ones(3),
            np.ones(3),
            np.array([0.0]),
            drill=DrillSpec(diameter_mm=2.0, tip_length_mm=0.6),
        )


def test_nearest_order_returns_voxel_values() -> None:
    vol, z_top = _slab_volume()
    entry = np.array([0.1, -0.2, z_top + 1.0])
    target = entry - np.array([0.0, 0.0, 10.0])
    depth = np.linspace(0.0, 2.5, 41) + 0.0037
    lip = sample_lip_rings(
        vol,
        entry,
        target,
        depth,
        drill=DrillSpec(diameter_mm=2.0, tip_length_mm=0.6),
        n_angles=5,
        order=0,
    )
    assert set(np.unique(lip.hu)) == {-1000.0, 1000.0}
    xi = depth[:, None] - 0.6 * lip.radii_mm[None, :]
    expected = np.where(xi > 1.0, 1000.0, -1000.0)  # the step sits halfway between voxel planes
    np.testing.assert_array_equal(lip.hu, np.broadcast_to(expected[:, :, None], lip.hu.shape))


def _lip_reference(
    vol: CTVolume, entry: np.ndarray, target: np.ndarray, depth: np.ndarray, outside_hu: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ring HU (D, R, A), outside counts (D,) and axis HU (D,) from the slow reference."""
    pts = lip_ring_points(entry, target, depth, drill=DrillSpec(diameter_mm=2.0, tip_length_mm=0.6))
    hu, inside = slow_trilinear(vol, pts, outside_hu=outside_hu)
    axis = axis_basis(entry, target)[0]
    axis_hu, _ = slow_trilinear(vol, entry + depth[:, None] * axis, outside_hu=outside_hu)
    outside = (~inside).reshape(depth.size, -1).sum(axis=1)
    return hu.reshape(pts.shape[:3]), outside, axis_hu


@pytest.mark.parametrize("padded", [False, True])
def test_lip_samples_match_the_slow_reference_on_the_demo_ct(padded: bool) -> None:
    vol = load_series(ASSETS / "demo" / "ct")
    plan = load_plan(ASSETS / "demo" / "plan.json")
    if padded:  # pad a slab the trajectory crosses, and the first slices
        valid = np.ones(vol.hu.shape, dtype=bool)
        valid[:, 40:44, :] = False
        valid[:3] = False
        vol = _volume(np.asarray(vol.hu), np.asarray(vol.affine_lps), valid)
    entry, target = np.asarray(plan.entry_lps), np.asarray(plan.target_lps)
    # The same axis run from far before the entry to far beyond the volume.
    depth = np.arange(-40.0, 60.0, 0.05)
    for outside_hu in (-1000.0, 55.0):
        got = sample_lip_rings(
            vol,
            entry,
            target,
            depth,
            drill=DrillSpec(diameter_mm=2.0, tip_length_mm=0.6),
            outside_hu=outside_hu,
        )
        hu, outside, axis_hu = _lip_reference(vol, entry, target, depth, outside_hu)
        np.testing.assert_allclose(got.hu, hu, rtol=0, atol=1e-3)
        np.testing.assert_allclose(got.axis_hu, axis_hu, rtol=0, atol=1e-3)
        np.testing.assert_array_equal(got.outside, outside)
        assert 0 < int(got.outside.sum()) < got.hu.size  # both kinds of sample occur
