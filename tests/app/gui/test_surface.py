"""The full-resolution bone surface: exact on linear fields in any frame (oblique, sheared,
irregular stacks), normals out of the bone, every slice used, and pieces that add up."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest

from ctdrill.app.gui.compute import volume_surface
from ctdrill.app.gui.surface import (
    block_for,
    block_grid,
    bone_surface,
    contour_grid,
    display_block,
    piece_count,
    surface_piece,
)
from ctdrill.imaging import CTVolume, SeriesInfo, load_series

PHILIPS = "dcmqa_ct_Philips_phantom_notilt_5mm"
SHAPE = (20, 22, 24)  # slices, rows, cols
#: A linear field HU(p) = GRAD . p + offset, in LPS: its iso-surface is a plane, exactly.
GRAD = np.array([30.0, -20.0, 45.0])
ISO = 150.0


def _linear_volume(affine: np.ndarray, positions: np.ndarray | None = None) -> CTVolume:
    """float32 HU of the linear field sampled at the true voxel centres."""
    nk, nj, ni = SHAPE
    k, j, i = np.meshgrid(np.arange(nk), np.arange(nj), np.arange(ni), indexing="ij")
    ijk = np.stack([i, j, k], axis=-1).astype(np.float64)
    vol0 = CTVolume(
        hu=np.zeros(SHAPE, np.float32),
        affine_lps=affine,
        valid=None,
        info=SeriesInfo(series_uid="1"),
        slice_positions_mm=positions if positions is not None else np.empty(0),
    )
    lps = vol0.index_to_lps(ijk)
    hu = (lps @ GRAD + _offset(vol0)).astype(np.float32)
    return CTVolume(
        hu=hu,
        affine_lps=affine,
        valid=None,
        info=SeriesInfo(series_uid="1"),
        slice_positions_mm=vol0.slice_positions_mm,
    )


def _offset(vol: CTVolume) -> float:
    """The field's offset that puts its iso-plane through the volume's centre."""
    centre = vol.index_to_lps((np.array(SHAPE[::-1]) - 1.0) / 2.0)
    return float(ISO - centre @ GRAD)


def _interior(vol: CTVolume, pts: np.ndarray, margin: float = 2.0) -> np.ndarray:
    """Points at least ``margin`` voxels inside the volume (away from the closing air pad)."""
    idx = vol.lps_to_index(pts)
    top = np.array(vol.hu.shape[::-1]) - 1.0
    return np.asarray(np.all((idx >= margin) & (idx <= top - margin), axis=1))


def _sheared_affine() -> np.ndarray:
    """Oblique axes with a gantry-tilt shear: slices step along S and along P."""
    rot = np.array([[0.96, -0.28, 0.0], [0.28, 0.96, 0.0], [0.0, 0.0, 1.0]])
    lin = rot @ np.diag([0.7, 0.8, 1.0])
    lin[:, 2] = [0.0, 0.42, 1.25]  # sheared k column
    aff = np.eye(4)
    aff[:3, :3] = lin
    aff[:3, 3] = [-5.0, 3.0, -7.0]
    return aff


@pytest.mark.parametrize("frame", ["identity", "sheared", "irregular"])
def test_the_surface_of_a_linear_field_is_its_plane_with_the_plane_normal(frame: str) -> None:
    aff = np.eye(4) if frame == "identity" else _sheared_affine()
    positions = None
    if frame == "irregular":  # uneven gaps between the slices, along the sheared normal
        normal = np.cross(aff[:3, 0], aff[:3, 1])
        normal /= np.linalg.norm(normal)
        step = float(aff[:3, 2] @ normal)
        gaps = step * np.array([1, 1, 3, 1, 0.5, 1, 2, 1, 1, 1, 4, 1, 1, 1, 2, 1, 1, 0.7, 1])
        positions = float(aff[:3, 3] @ normal) + np.concatenate([[0.0], np.cumsum(gaps)])
    vol = _linear_volume(aff, positions)
    surf = volume_surface(vol, iso_hu=ISO)
    pts = np.asarray(surf.points)
    inner = _interior(vol, pts)
    assert inner.sum() > 50
    # Linear interpolation of a linear field is exact: every interior vertex is on the plane.
    np.testing.assert_allclose(pts[inner] @ GRAD + _offset(vol), ISO, atol=1e-3)
    normals = np.asarray(surf.point_data["Normals"])
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-6)
    want = -GRAD / np.linalg.norm(GRAD)  # out of the bone: towards lower HU
    cos = normals[inner] @ want
    if frame == "irregular":  # the voxel gradient differences across uneven gaps
        assert np.min(cos) > np.cos(np.deg2rad(25.0))
        assert np.median(cos) > np.cos(np.deg2rad(2.0))
    else:
        np.testing.assert_allclose(cos, 1.0, atol=1e-5)


def test_normals_point_out_of_a_bone_ball() -> None:
    c = np.array([10.0, 12.0, 9.0])
    k, j, i = np.meshgrid(np.arange(20), np.arange(24), np.arange(22), indexing="ij")
    r = np.sqrt((i - c[0]) ** 2 + (j - c[1]) ** 2 + (k - c[2]) ** 2)
    hu = np.where(r <= 6.0, 1200, -1000).astype(np.int16)
    surf = bone_surface(hu, np.eye(4), iso_hu=300.0)
    pts = np.asarray(surf.points)
    out = np.einsum("ij,ij->i", np.asarray(surf.point_data["Normals"]), pts - c)
    assert np.all(out > 0)
    assert np.linalg.norm(pts - c, axis=1) == pytest.approx(6.0, abs=0.6)


def test_pieces_add_up_to_the_surface_slab_by_slab() -> None:
    k, j, i = np.meshgrid(np.arange(40), np.arange(30), np.arange(30), indexing="ij")
    hu = np.where(np.hypot(i - 15, j - 15) <= 9 + 2 * np.sin(k / 3.0), 900, -1000)
    hu = hu.astype(np.int16)
    whole = bone_surface(hu, np.eye(4), iso_hu=0.0, piece_triangles=10**9)
    cut = bone_surface(hu, np.eye(4), iso_hu=0.0, piece_triangles=700)
    assert piece_count(whole) == 1 and surface_piece(whole, 0).n_cells == whole.n_cells
    n = piece_count(cut)
    assert n == int(np.ceil(whole.n_cells / 700))

    def triangles(mesh: object) -> np.ndarray:
        pts = np.asarray(mesh.points)  # type: ignore[attr-defined]
        tri = pts[np.asarray(mesh.regular_faces)]  # type: ignore[attr-defined]
        rows = np.round(tri.reshape(len(tri), 9), 6)
        return rows[np.lexsort(rows.T[::-1])]

    pieces = [surface_piece(cut, m) for m in range(n)]
    assert all(p.n_cells <= 700 for p in pieces)
    np.testing.assert_array_equal(
        triangles(whole),
        np.concatenate([triangles(p) for p in pieces])[
            np.lexsort(np.concatenate([triangles(p) for p in pieces]).T[::-1])
        ],
    )
    # A piece is a slab: its slice range overlaps the next one's by at most one slice.
    z_ranges = [(float(p.points[:, 2].min()), float(p.points[:, 2].max())) for p in pieces]
    for (_, hi), (lo, _) in itertools.pairwise(z_ranges):
        assert lo >= hi - 1.0 - 1e-9


def test_the_real_head_surface_has_vertices_on_every_slice(shared_data: Path) -> None:
    vol = load_series(shared_data / PHILIPS)
    surf = volume_surface(vol, iso_hu=300.0)
    bone_slices = set(np.flatnonzero((vol.hu > 300).any(axis=(1, 2))).tolist())
    assert len(bone_slices) >= 20
    # Full resolution: every slice with bone carries the in-plane contour (many vertices at
    # exactly its k); the earlier strided surface only every 4th slice (rings 20 mm apart).
    assert bone_slices <= _dense_slices(vol, surf)
    coarse = bone_surface(vol.hu, vol.affine_lps, iso_hu=300.0, max_dim=160)
    assert {k % 4 for k in _dense_slices(vol, coarse)} == {0}


def _dense_slices(vol: CTVolume, surf: object, least: int = 20) -> set[int]:
    """Slices (in the volume) holding at least ``least`` vertices at exactly their k."""
    k = vol.lps_to_index(np.asarray(surf.points))[:, 2]  # type: ignore[attr-defined]
    on_slice = np.abs(k - np.round(k)) < 1e-4
    ks, counts = np.unique(np.round(k[on_slice]).astype(int), return_counts=True)
    return {int(x) for x, c in zip(ks, counts, strict=True) if c >= least and 0 <= x < vol.dims[2]}


@pytest.mark.parametrize("block", [(2, 2, 1), (3, 2, 2)])
def test_a_block_averaged_surface_of_a_linear_field_is_still_its_plane(
    block: tuple[int, int, int],
) -> None:
    # The mean of a linear field over a block is its value at the block's centre, where the
    # sample is placed: the plane comes out exactly, whatever the block.
    vol = _linear_volume(_sheared_affine())
    surf = bone_surface(
        vol.hu, vol.affine_lps, iso_hu=ISO, index_to_lps=vol.index_to_lps, block=block
    )
    assert tuple(surf.field_data["block"]) == block
    pts = np.asarray(surf.points)
    inner = _interior(vol, pts, margin=2.0 * max(block))
    assert inner.sum() > 10
    np.testing.assert_allclose(pts[inner] @ GRAD + _offset(vol), ISO, atol=1e-3)


def test_block_sizes_follow_the_spacing() -> None:
    assert block_for((0.4, 0.4, 0.3), 1.3) == (3, 3, 4)
    assert block_for((0.45, 0.45, 5.0), 1.0) == (2, 2, 1)  # thick slices stay whole
    assert block_for((0.4, 0.4, 0.3), 1.3, merge_slices=False) == (3, 3, 1)
    assert block_for((0.4, 0.4, 0.3), 0.1) == (1, 1, 1)


def test_the_display_block_is_the_first_within_the_budget() -> None:
    k, j, i = np.meshgrid(np.arange(60), np.arange(64), np.arange(64), indexing="ij")
    hu = np.where(np.hypot(i - 32, j - 32) + 3 * np.sin(k / 4.0) <= 25, 900, -1000)
    hu = hu.astype(np.int16)
    spacing = (0.5, 0.5, 0.5)

    def count(block: tuple[int, int, int]) -> int:
        return int(contour_grid(block_grid(hu, block=block), 0.0, normals=False).n_cells)

    full = count((1, 1, 1))
    assert display_block(hu, spacing, iso_hu=0.0, max_triangles=full) == (1, 1, 1)
    got = display_block(hu, spacing, iso_hu=0.0, max_triangles=full // 5)
    assert got != (1, 1, 1) and count(got) <= full // 5
    # thick slices: only the pixels are merged
    got_thick = display_block(hu, (0.5, 0.5, 5.0), iso_hu=0.0, max_triangles=full // 3)
    assert got_thick[2] == 1 and count(got_thick) <= full // 3


def test_the_refinement_budget_follows_the_measured_frames() -> None:
    from ctdrill.app.gui.view3d import (
        FRAME_BUDGET_S,
        REFINE_GAIN,
        REFINE_SAFETY,
        refine_budget,
    )

    # 20 ms without the bone, 40 ms with 50k triangles: 0.4 us a triangle, 80 ms of room.
    want = int(REFINE_SAFETY * (FRAME_BUDGET_S - 0.020) / (0.020 / 50_000))
    assert refine_budget(50_000, 0.020, 0.040) == pytest.approx(want, abs=1)
    assert want == pytest.approx(140_000, abs=1)
    # too slow already, or too little gain: no refinement
    assert refine_budget(50_000, 0.020, 0.150) is None
    assert refine_budget(50_000, 0.020, 0.020 + 0.080 * REFINE_SAFETY / REFINE_GAIN * 1.01) is None
    # noise: a frame with the bone faster than without still counts 10 % of it as the bone's
    assert refine_budget(10_000, 0.030, 0.025) == pytest.approx(
        REFINE_SAFETY * 0.075 / (0.0025 / 10_000), abs=1
    )
    assert refine_budget(0, 0.01, 0.02) is None
    assert refine_budget(1000, float("nan"), 0.02) is None


@pytest.mark.parametrize("block", [(2, 3, 4), (1, 1, 2), (3, 3, 1)])
def test_block_means_count_every_voxel_and_pad_with_air(block: tuple[int, int, int]) -> None:
    rng = np.random.default_rng(7)
    hu = rng.integers(-1000, 2000, size=(23, 17, 19)).astype(np.int16)
    valid = rng.random(hu.shape) > 0.1
    grid = block_grid(hu, block=block, valid=valid)
    fi, fj, fk = block
    nk, nj, ni = hu.shape
    nb = (-(-nk // fk), -(-nj // fj), -(-ni // fi))
    # the reference: the volume padded with air to whole blocks, invalid voxels air, then means
    full = np.full((nb[0] * fk, nb[1] * fj, nb[2] * fi), -1000.0)
    full[:nk, :nj, :ni] = np.where(valid, hu, -1000)
    want = full.reshape(nb[0], fk, nb[1], fj, nb[2], fi).mean(axis=(1, 3, 5))
    assert grid.shape == tuple(n + 2 for n in nb)
    np.testing.assert_allclose(grid[1:-1, 1:-1, 1:-1], want, atol=1e-3)
    assert np.all(grid[0] == -1000) and np.all(grid[:, :, -1] == -1000)  # the closing layer
