"""Panoramic reformat and cross-sections: every expected value known in closed form."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ctdrill.imaging.dicom.series import load_series
from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.phantom.field import CANAL_HU
from ctdrill.imaging.phantom.mandible import make_mandible_phantom
from ctdrill.imaging.sampling.arch import ArchCurve, ArchInputError
from ctdrill.imaging.sampling.reformat import (
    MAX_PIXELS,
    arc_position_mm,
    cross_section,
    panorama,
)
from ctdrill.imaging.sampling.reformat_grid import SLAB_STEP_FRACTION, smallest_spacing_mm
from ctdrill.imaging.volume import CTVolume, SeriesInfo
from tests.imaging.factory import affine, rotation, volume

#: Gradient (HU/mm) and offset of the analytic field f(p) = G . p + C.
G = np.array([3.0, -2.0, 5.0])
C = 100.0


def f(p: np.ndarray) -> np.ndarray:
    return np.asarray(p @ G + C)


def linear_volume(*, tilt_deg: float = 0.0, positions: np.ndarray | None = None) -> CTVolume:
    """A float32 volume holding f at every voxel centre (exact for trilinear sampling)."""
    shape = (40, 50, 60)  # (slices, rows, cols)
    aff = affine(
        (0.8, 0.7, 1.1),
        rot=rotation(20.0, 8.0, -5.0),
        origin_lps=(-30.0, -25.0, -20.0),
        tilt_deg=tilt_deg,
    )
    base = CTVolume(
        hu=np.zeros(shape, np.float32),
        affine_lps=aff,
        valid=None,
        info=SeriesInfo(series_uid="1.2.3"),
        slice_positions_mm=np.empty(0) if positions is None else positions + _origin_pos(aff),
    )
    k, j, i = np.indices(shape)
    centres = base.index_to_lps(np.stack([i, j, k], axis=-1).astype(np.float64))
    return CTVolume(
        hu=f(centres).astype(np.float32),
        affine_lps=aff,
        valid=None,
        info=base.info,
        slice_positions_mm=base.slice_positions_mm,
    )


def _origin_pos(aff: np.ndarray) -> float:
    normal = np.cross(aff[:3, 0], aff[:3, 1])
    return float(aff[:3, 3] @ normal / np.linalg.norm(normal))


def circle_arch(
    radius: float, centre_xy: tuple[float, float], a0: float, a1: float, n: int, z: float
) -> np.ndarray:
    ang = np.linspace(a0, a1, n)
    return np.stack(
        [centre_xy[0] + radius * np.cos(ang), centre_xy[1] + radius * np.sin(ang), np.full(n, z)],
        axis=1,
    )


@pytest.fixture(scope="module")
def lin() -> CTVolume:
    return linear_volume()


def test_panorama_of_a_linear_field_is_the_field_at_every_pixel(lin: CTVolume) -> None:
    arch = circle_arch(18.0, (-2.0, -8.0), 0.3, 2.6, 9, z=0.0)
    r = panorama(lin, arch, pixel_mm=0.5, slab_mm=3.0, height_mm=12.0)
    inside = lin.inside(r.lps)
    assert inside.mean() > 0.95  # the test exercises the interior
    # Every slab sample of the interior pixels lies inside: the mean of a linear field over
    # a symmetric slab is its centre value.
    normal = ArchCurve(arch).frame(np.arange(r.shape[1]) * 0.5)[2]
    edge_in = lin.inside(r.lps + 1.5 * normal[None]) & lin.inside(r.lps - 1.5 * normal[None])
    ok = inside & edge_in
    np.testing.assert_allclose(r.hu[ok], f(r.lps[ok]), atol=2e-3)
    # MIP of a linear field over the slab: the centre value + half the slab x |G . normal|.
    mip = panorama(lin, arch, pixel_mm=0.5, slab_mm=3.0, slab_mode="mip", height_mm=12.0)
    expect = f(mip.lps) + 1.5 * np.abs(normal @ G)[None, :]
    np.testing.assert_allclose(mip.hu[ok], expect[ok], atol=2e-3)
    assert (
        r.slab_samples
        == int(np.ceil(3.0 / (SLAB_STEP_FRACTION * smallest_spacing_mm(lin)) - 1e-9)) + 1
    )


def test_outside_the_volume_is_minus_1000(lin: CTVolume) -> None:
    arch = np.array([[-60.0, 0.0, 0.0], [60.0, 5.0, 0.0]])  # runs out on both sides
    r = panorama(lin, arch, pixel_mm=1.0, slab_mm=0.0)
    out = ~lin.inside(r.lps)
    assert out.sum() > 100 and (~out).sum() > 100
    assert np.all(r.hu[out] == -1000.0)
    np.testing.assert_allclose(r.hu[~out], f(r.lps[~out]), atol=2e-3)  # field values > -500


def test_straight_arch_is_the_oblique_plane_of_ctvolume_sample() -> None:
    rng = np.random.default_rng(3)
    hu = rng.integers(-1000, 2000, size=(30, 40, 45)).astype(np.int16)
    vol = volume(hu, affine((0.6, 0.6, 1.3), rot=rotation(12.0, 0.0, 0.0)))
    a, b = np.array([-14.0, -22.0, 52.0]), np.array([2.0, -5.0, 52.0])
    r = panorama(vol, np.stack([a, b]), pixel_mm=0.4, slab_mm=0.0, height_mm=20.0)
    d = (b - a) / np.linalg.norm(b - a)
    h, w = r.shape
    z_top = 52.0 + 0.5 * (h - 1) * 0.4
    i, j = np.mgrid[0:h, 0:w]
    pts = a + (j * 0.4)[..., None] * d + ((z_top - i * 0.4) - 52.0)[..., None] * np.array([0, 0, 1])
    np.testing.assert_allclose(r.lps, pts, atol=1e-9)
    np.testing.assert_allclose(r.hu, vol.sample(pts), atol=1e-6)
    assert r.hu.std() > 100  # real structure, not a constant


def test_circular_arch_positions_in_closed_form_and_normals_never_jump() -> None:
    vol = volume(np.zeros((4, 71, 71), np.int16), affine((1.0, 1.0, 1.0), origin_lps=(-35, -35, 8)))
    radius, n = 30.0, 7
    arch = circle_arch(radius, (0.0, 0.0), 0.0, np.pi, n, z=10.0)
    step = np.pi / (n - 1)
    chord = 2 * radius * np.sin(step / 2)
    r = panorama(vol, arch, pixel_mm=0.25, slab_mm=0.0, height_mm=1.0, tangent_window_mm=8.0)
    s = np.arange(r.shape[1]) * 0.25
    seg = np.minimum((s // chord).astype(int), n - 2)
    frac = (s - seg * chord) / chord
    expect = arch[seg] + frac[:, None] * (arch[seg + 1] - arch[seg])
    np.testing.assert_allclose(r.lps[0, :, :2], expect[:, :2], atol=1e-9)
    np.testing.assert_allclose(r.lps[:, 0, 2], [10.5, 10.25, 10.0, 9.75, 9.5])  # +-0.5 mm
    # The normal turns by the polygon's exterior angle over the 8 mm window, never at once: at
    # most 2 tan(angle / 2) / window rad per mm (the chord's turning rate at the vertex).
    normal = ArchCurve(arch, 8.0).frame(s)[2]
    turn = np.arccos(np.clip(np.sum(normal[1:] * normal[:-1], axis=1), -1, 1))
    assert turn.max() <= 2 * np.tan(step / 2) / 8.0 * 0.25 + 1e-9
    assert turn.sum() == pytest.approx(step * (n - 2), abs=1e-7)  # arccos rounding
    # Far from every vertex (more than half the window) it is the segment's own normal.
    far = np.abs(s - np.round(s / chord) * chord) > 4.0 + 1e-6
    seg_dir = (arch[seg + 1] - arch[seg])[:, :2] / chord
    np.testing.assert_allclose(
        normal[far, :2], np.stack([-seg_dir[far, 1], seg_dir[far, 0]], 1), atol=1e-12
    )
    assert r.column_letters == ("L", "R")  # the arch starts at +x (patient left)


def test_projection_round_trip_panorama_and_cross_section(lin: CTVolume) -> None:
    arch = circle_arch(20.0, (-2.0, -8.0), 0.2, 2.8, 6, z=0.0)
    r = panorama(lin, arch, pixel_mm=0.7, slab_mm=2.0, height_mm=15.0)
    h, w = r.shape
    i, j = np.mgrid[0:h, 0:w]
    uv, off = r.project(r.lps.reshape(-1, 3))
    np.testing.assert_allclose(uv[:, 0], j.ravel() * 0.7, atol=1e-7)
    np.testing.assert_allclose(uv[:, 1], i.ravel() * 0.7, atol=1e-9)
    np.testing.assert_allclose(off, 0.0, atol=1e-7)
    # Off the curtain along the column normal: same pixel, offset the distance.
    normal = ArchCurve(arch).frame(np.arange(w) * 0.7)[2]
    moved = r.lps + 1.3 * normal[None]
    uv2, off2 = r.project(moved.reshape(-1, 3))
    np.testing.assert_allclose(uv2, uv, atol=1e-7)
    np.testing.assert_allclose(off2, 1.3, atol=1e-7)
    # The local directions: tangent (columns), -z (rows), the normal (slab).
    col_dir, row_dir, slab_dir = r.directions_lps(r.lps[0])
    np.testing.assert_allclose(slab_dir, normal, atol=1e-9)
    np.testing.assert_allclose(
        np.cross(col_dir, slab_dir), np.tile([0.0, 0.0, 1.0], (w, 1)), atol=1e-9
    )
    np.testing.assert_allclose(row_dir, np.tile([0.0, 0.0, -1.0], (w, 1)))
    # Beyond the arch's ends: NaN.
    start = arch[0] - 5.0 * (arch[1] - arch[0]) / np.linalg.norm(arch[1] - arch[0])
    assert np.all(np.isnan(r.project(start[None])[0]))
    c = cross_section(lin, arch, at_arc_mm=10.0, pixel_mm=0.5, width_mm=12.0, height_mm=9.0)
    ch, cw = c.shape
    i, j = np.mgrid[0:ch, 0:cw]
    uv, off = c.project(c.lps.reshape(-1, 3))
    np.testing.assert_allclose(uv, np.stack([j.ravel(), i.ravel()], 1) * 0.5, atol=1e-9)
    np.testing.assert_allclose(off, 0.0, atol=1e-9)


def test_lps_at_inverts_project_on_the_surface_and_hits_every_pixel_centre(lin: CTVolume) -> None:
    arch = circle_arch(20.0, (-2.0, -8.0), 0.2, 2.8, 6, z=1.5)
    r = panorama(lin, arch, pixel_mm=0.7, slab_mm=2.0, height_mm=15.0, centre_z_mm=-2.0)
    h, w = r.shape
    assert float(r.lps[h // 2, 0, 2]) == pytest.approx(-2.0)  # the rows' middle where asked
    i, j = np.mgrid[0:h, 0:w]
    centres = r.lps_at(np.stack([j, i], axis=-1) * 0.7)
    np.testing.assert_allclose(centres, r.lps, atol=1e-9)
    # between pixel centres: on the curtain (offset 0), projecting back where it was taken
    rng = np.random.default_rng(27)
    uv = rng.uniform([0.0, 0.0], [(w - 1) * 0.7, (h - 1) * 0.7], size=(200, 2))
    back, off = r.project(r.lps_at(uv))
    np.testing.assert_allclose(back, uv, atol=1e-7)
    np.testing.assert_allclose(off, 0.0, atol=1e-7)
    assert np.all(np.isnan(r.lps_at(np.array([-1.0, 3.0]))))  # before the arch's start
    c = cross_section(lin, arch, at_arc_mm=10.0, pixel_mm=0.5, width_mm=12.0, height_mm=9.0)
    ch, cw = c.shape
    i, j = np.mgrid[0:ch, 0:cw]
    np.testing.assert_allclose(c.lps_at(np.stack([j, i], -1) * 0.5), c.lps, atol=1e-9)
    back, off = c.project(c.lps_at(uv[:20] * 0.1))
    np.testing.assert_allclose(back, uv[:20] * 0.1, atol=1e-9)
    np.testing.assert_allclose(off, 0.0, atol=1e-9)


def test_cross_section_contains_the_axis_and_scrolls_along_the_arch(lin: CTVolume) -> None:
    arch = np.array([[-20.0, -10.0, 0.0], [20.0, -10.0, 0.0]])  # along +x: normal is +y
    entry, target = np.array([1.0, -9.0, 8.0]), np.array([2.0, -12.0, -2.0])  # tilted
    c = cross_section(lin, arch, axis=(entry, target), pixel_mm=0.5, slab_mm=0.0)
    assert c.at_arc_mm == pytest.approx(21.5)
    _uv, off = c.project(np.stack([entry, target, 0.5 * (entry + target)]))
    np.testing.assert_allclose(off, 0.0, atol=1e-12)
    marker = c.arch_point_lps()
    assert marker is not None
    np.testing.assert_allclose(marker, [1.5, -10.0, 0.0], atol=1e-12)
    assert panorama(lin, arch, slab_mm=0.0, height_mm=2.0).arch_point_lps() is None
    assert c.plane_lps is not None
    centre, col, row, normal = c.plane_lps
    np.testing.assert_allclose(centre, 0.5 * (entry + target))
    np.testing.assert_allclose(col, [0.0, 1.0, 0.0])
    assert row[2] < 0  # rows run down
    assert c.column_letters == ("A", "P")  # a straight arch has no inside: patient directions
    np.testing.assert_allclose(np.cross(col, -row), normal)
    np.testing.assert_allclose(c.hu, lin.sample(c.lps), atol=1e-9)
    moved = cross_section(
        lin, arch, axis=(entry, target), at_arc_mm=26.5, pixel_mm=0.5, slab_mm=0.0
    )
    np.testing.assert_allclose(moved.lps, c.lps + np.array([5.0, 0.0, 0.0]), atol=1e-9)
    with pytest.raises(ImagingInputError, match="bucco-lingual"):
        cross_section(lin, arch, axis=(np.array([0.0, 0.0, 0.0]), np.array([0.0, -5.0, 0.0])))
    with pytest.raises(ImagingInputError, match="outside the arch"):
        cross_section(lin, arch, at_arc_mm=41.0)
    # The slab mean of a linear field is the centre value (a symmetric slab).
    thick = cross_section(lin, arch, axis=(entry, target), pixel_mm=0.5, slab_mm=2.0)
    ok = lin.inside(thick.lps + normal) & lin.inside(thick.lps - normal)
    np.testing.assert_allclose(thick.hu[ok], f(thick.lps[ok]), atol=2e-3)


def test_arc_position_of_a_point() -> None:
    arch = circle_arch(30.0, (0.0, 0.0), 0.0, np.pi / 2, 91, z=0.0)
    point = np.array([30.0 * np.cos(0.5), 30.0 * np.sin(0.5), 7.0]) * [1.1, 1.1, 1.0]
    # A dense polygon: the arc position is the angle x radius up to the chord's sag.
    assert arc_position_mm(arch, point) == pytest.approx(15.0, abs=0.01)
    with pytest.raises(ArchInputError, match="beyond the arch"):
        arc_position_mm(arch, np.array([40.0, -10.0, 0.0]))


def test_bad_arch_and_options_refused(lin: CTVolume) -> None:
    with pytest.raises(ArchInputError, match="vertical"):
        panorama(lin, np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 9.0]]))
    with pytest.raises(ArchInputError, match="folds back"):
        panorama(lin, np.array([[0.0, 0.0, 0.0], [5.0, 0.0, 0.0], [0.0, 0.0, 0.0]]))
    with pytest.raises(ImagingInputError, match="slab mode"):
        panorama(lin, np.array([[0.0, 0.0, 0.0], [5.0, 0.0, 0.0]]), slab_mode="max")  # type: ignore[arg-type]
    with pytest.raises(ImagingInputError, match="pixels"):
        panorama(lin, np.array([[0.0, 0.0, 0.0], [500.0, 0.0, 0.0]]), pixel_mm=0.01)
    assert MAX_PIXELS < 10_000_000


def test_default_pixel_is_the_smallest_spacing() -> None:
    arch = np.array([[-10.0, -5.0, 0.0], [10.0, -5.0, 0.0]])
    assert panorama(linear_volume(), arch, slab_mm=0.0).pixel_mm == pytest.approx(0.7)
    positions = np.cumsum(np.r_[0.0, np.full(19, 1.1), 0.4, np.full(19, 2.0)])
    irregular = linear_volume(positions=positions)
    assert panorama(irregular, arch, slab_mm=0.0).pixel_mm == pytest.approx(0.4)


def test_irregular_tilted_stack_matches_ctvolume_sample() -> None:
    positions = np.cumsum(np.r_[0.0, np.full(19, 1.1), 0.4, np.full(19, 2.0)])
    vol = linear_volume(tilt_deg=15.0, positions=positions)
    arch = circle_arch(15.0, (-2.0, -5.0), 0.4, 2.4, 5, z=10.0)
    r = panorama(vol, arch, pixel_mm=0.5, slab_mm=0.0)
    inside = vol.inside(r.lps)
    assert inside.sum() > 1000
    np.testing.assert_allclose(r.hu[inside], f(r.lps[inside]), atol=3e-3)
    assert np.all(r.hu[~inside] == -1000.0)


def test_demo_phantom_canal_in_the_panorama() -> None:
    ph = make_mandible_phantom()
    vol = volume(ph.hu, ph.affine_lps)
    g = ph.geometry
    cx, cy = g.arch_centre_xy_lps
    arch = circle_arch(g.arch_radius_mm, (cx, cy), -0.45, 0.45, 15, z=-33.0)
    r = panorama(vol, arch, slab_mm=0.0)
    uv, off = r.project(ph.canal_centerline_lps)
    # The canal lies on the arch's circle: offset within the polygon's sag, at z -43.
    sag = g.arch_radius_mm * (1 - np.cos(0.9 / 14 / 2))
    assert np.nanmax(np.abs(off)) <= sag + 1e-9
    z_canal = ph.canal_centerline_lps[:, 2]
    np.testing.assert_allclose(uv[:, 1], r.lps[0, 0, 2] - z_canal, atol=1e-9)
    # In the middle column, the darkest pixel within the bone body is the canal's centre row.
    col = r.shape[1] // 2
    row_canal = round((r.lps[0, 0, 2] - float(np.mean(z_canal))) / r.pixel_mm)
    window = slice(row_canal - 10, row_canal + 11)
    dark = int(np.argmin(r.hu[window, col])) + row_canal - 10
    assert abs(dark - row_canal) <= 1
    assert r.hu[row_canal, col] == pytest.approx(CANAL_HU, abs=60)


def test_real_gantry_tilt_head(shared_data: Path) -> None:
    vol = load_series(shared_data / "dcmqa_ct_GE_head_gantrytilt_varspacing")
    lo = vol.index_to_lps(np.array([0.0, 0.0, 0.0]))
    hi = vol.index_to_lps(np.array([vol.dims[0] - 1.0, vol.dims[1] - 1.0, vol.dims[2] - 1.0]))
    mid = 0.5 * (lo + hi)
    arch = circle_arch(60.0, (mid[0], mid[1]), 0.3, 2.8, 12, z=mid[2])
    r = panorama(vol, arch, pixel_mm=1.0, slab_mm=4.0)
    normal = ArchCurve(arch).frame(np.arange(r.shape[1]) * 1.0)[2]
    offsets = np.linspace(-2.0, 2.0, r.slab_samples)
    expect = np.mean(
        [vol.sample(r.lps + t * normal[None], outside_hu=-1000.0) for t in offsets], axis=0
    )
    np.testing.assert_allclose(r.hu, expect, atol=1e-9)
    assert (r.hu > 0).mean() > 0.05  # bone and brain are in the picture


def test_cross_section_sides_buccal_and_lingual() -> None:
    """A U-shaped arch from the patient's right molars (x -20) through the incisors (y -28,
    anterior) to the left molars: at the incisors the arch's inside is posterior (+y)."""
    flat = volume(
        np.zeros((9, 81, 81), np.int16), affine((1.0, 1.0, 1.0), origin_lps=(-40, -40, -4))
    )
    ang = np.linspace(np.pi, 0.0, 13)
    arch = np.stack([20.0 * np.cos(ang), -8.0 - 20.0 * np.sin(ang), np.zeros(13)], axis=1)
    mid = ArchCurve(arch).length_mm / 2
    c = cross_section(flat, arch, at_arc_mm=mid, pixel_mm=0.5, width_mm=10.0, height_mm=4.0)
    assert c.plane_lps is not None
    np.testing.assert_allclose(c.plane_lps[1], [0.0, 1.0, 0.0], atol=1e-12)  # columns +y
    assert c.column_letters == ("B", "Li")  # buccal (anterior) on the left
    reverse = cross_section(
        flat, arch[::-1], at_arc_mm=mid, pixel_mm=0.5, width_mm=10.0, height_mm=4.0
    )
    assert reverse.column_letters == ("Li", "B")
    pano = panorama(flat, arch, pixel_mm=1.0, slab_mm=0.0, height_mm=2.0)
    assert pano.column_letters == ("R", "L")


def test_image_wholly_outside_the_ct_is_refused_and_coverage_recorded(lin: CTVolume) -> None:
    """An arch in the wrong frame (RAS read as LPS: x and y negated, far off here) samples
    nothing of the CT: refused, never an all-air image."""
    arch = np.array([[200.0, 200.0, 0.0], [240.0, 200.0, 0.0]])
    with pytest.raises(ImagingInputError, match=r"outside the CT.*coordinate_system"):
        panorama(lin, arch, pixel_mm=1.0)
    with pytest.raises(ImagingInputError, match="cross-section: the whole image"):
        cross_section(lin, arch, at_arc_mm=20.0, pixel_mm=1.0)
    half = np.array([[-60.0, 0.0, 0.0], [60.0, 5.0, 0.0]])
    r = panorama(lin, half, pixel_mm=1.0, slab_mm=0.0)
    assert r.inside_fraction == pytest.approx(float(lin.inside(r.lps).mean()))
    assert 0.0 < r.inside_fraction < 1.0
    assert r.metadata()["inside_fraction"] == r.inside_fraction
