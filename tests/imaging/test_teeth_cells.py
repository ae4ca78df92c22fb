"""The implant-to-tooth distance reads only the cells of tooth voxels that may hold a nearer one:
the same answer, bit for bit, as every voxel read (random teeth, random implants, inside a
tooth, beyond the neighbourhood), and as the plain formula to rounding."""

from __future__ import annotations

import numpy as np
import pytest

from ctdrill.imaging import teeth
from ctdrill.imaging.provenance import SeriesInfo
from ctdrill.imaging.teeth import (
    NEIGHBOUR_MM,
    TOOTH_CELL_MM,
    body_distances_mm,
    tooth_cells,
    tooth_distance_mm,
    tooth_points_lps,
)
from ctdrill.imaging.volume import CTVolume

RADII = np.array([2.05, 2.05, 2.0, 1.9, 1.7, 1.4])  # a tapered body, platform to apex


def _teeth_volume(
    rng: np.random.Generator, n_teeth: int, spacing: float = 0.5, size: float = 6.0
) -> CTVolume:
    """A 60 x 50 x 40 mm CT with ``n_teeth`` ellipsoids of 2600 HU (and an oblique affine)."""
    shape = (80, 100, 120)
    hu = np.full(shape, 300, dtype=np.int16)
    k, j, i = np.indices(shape)
    for _ in range(n_teeth):
        c = rng.uniform([10, 10, 10], [70, 90, 110])
        r = rng.uniform(2.0, size, size=3)
        hu[((k - c[0]) / r[0]) ** 2 + ((j - c[1]) / r[1]) ** 2 + ((i - c[2]) / r[2]) ** 2 <= 1] = (
            2600
        )
    angle = 0.3
    rot = np.array(
        [[np.cos(angle), -np.sin(angle), 0.0], [np.sin(angle), np.cos(angle), 0.0], [0, 0, 1.0]]
    )
    affine = np.eye(4)
    affine[:3, :3] = rot * spacing
    affine[:3, 3] = [-30.0, -25.0, -20.0]
    return CTVolume(hu, affine, None, SeriesInfo(series_uid="1.2.3"))


def _reference(
    volume: CTVolume, platform: np.ndarray, axis: np.ndarray, length: float
) -> float | None:
    """The plain formula over every tooth voxel (independent of the cells)."""
    pts = tooth_points_lps(volume)
    if len(pts) == 0:
        return None
    rel = pts - platform
    s = rel @ axis
    s_clip = np.clip(s, 0.0, length)
    radial = np.linalg.norm(rel - s[:, None] * axis, axis=1)
    near = (radial <= NEIGHBOUR_MM) & (np.abs(s - s_clip) <= NEIGHBOUR_MM)
    if not near.any():
        return None
    radius = np.interp(s_clip[near], np.linspace(0.0, length, len(RADII)), RADII)
    along = s[near] - s_clip[near]
    out = np.sqrt(np.maximum(radial[near] - radius, 0.0) ** 2 + along**2)
    out = np.where((along == 0.0) & (radial[near] < radius), radial[near] - radius, out)
    return float(out.min())


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_cells_give_every_voxels_answer(seed: int) -> None:
    rng = np.random.default_rng(seed)
    volume = _teeth_volume(rng, n_teeth=6)
    cells = tooth_cells(volume)
    pts = tooth_points_lps(volume)
    assert len(cells.points_lps) == len(pts) > 1000 and len(cells.centres_lps) > 10
    # every voxel lies within its cell's half diagonal of the cell's centre
    for c in range(len(cells.centres_lps)):
        inside = cells.points_lps[cells.starts[c] : cells.starts[c + 1]]
        assert np.linalg.norm(inside - cells.centres_lps[c], axis=1).max() <= (
            cells.half_diagonal_mm + 1e-9
        )
    inside_tooth = near_none = 0
    for _ in range(60):
        platform = rng.uniform([-35, -30, -25], [35, 30, 25])
        if rng.random() < 0.3:  # a platform on a tooth voxel: inside it
            platform = pts[rng.integers(len(pts))] + rng.normal(scale=0.3, size=3)
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        length = float(rng.uniform(6.0, 16.0))
        got = tooth_distance_mm(volume, platform, axis, length, RADII)
        every = body_distances_mm(pts, platform, axis, length, RADII)
        want = None if not np.isfinite(every.min()) else float(every.min())
        assert got == want  # bit for bit
        ref = _reference(volume, platform, axis, length)
        assert (got is None) == (ref is None)
        if got is not None and ref is not None:
            assert got == pytest.approx(ref, abs=1e-9)
            inside_tooth += got < 0.0
        else:
            near_none += 1
    assert inside_tooth > 0  # the cases include bodies inside a tooth


def test_far_from_every_tooth_and_no_teeth() -> None:
    rng = np.random.default_rng(5)
    volume = _teeth_volume(rng, n_teeth=2)
    far = np.array([0.0, 0.0, 200.0])  # beyond the neighbourhood of every voxel
    assert tooth_distance_mm(volume, far, np.array([0.0, 0.0, -1.0]), 10.0, RADII) is None
    empty = CTVolume(np.zeros((4, 4, 4), dtype=np.int16), np.eye(4), None, volume.info)
    assert tooth_distance_mm(empty, np.zeros(3), np.array([0.0, 0.0, 1.0]), 10.0, RADII) is None
    assert tooth_cells(empty).points_lps.shape == (0, 3)


def test_few_cells_are_read_for_a_body_beside_a_tooth(monkeypatch: pytest.MonkeyPatch) -> None:
    rng = np.random.default_rng(7)
    volume = _teeth_volume(rng, n_teeth=8, size=14.0)
    pts = tooth_points_lps(volume)
    assert len(pts) > 10_000
    read: list[int] = []
    body = teeth.body_distances_mm

    def counted(points: np.ndarray, *args: object) -> np.ndarray:
        read.append(len(points))
        return body(points, *args)  # type: ignore[arg-type]

    monkeypatch.setattr(teeth, "body_distances_mm", counted)
    platform = pts[0] + np.array([0.0, 0.0, 3.0 + TOOTH_CELL_MM])
    got = tooth_distance_mm(volume, platform, np.array([0.0, 0.0, 1.0]), 10.0, RADII)
    assert got is not None
    assert sum(read) < len(pts) / 4  # the nearest cells only
