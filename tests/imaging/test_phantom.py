"""The analytic mandible phantom: exact HU at known points, canal truth, plan, noise, streaks."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from ctdrill.imaging.misch import MISCH_BANDS_HU
from ctdrill.imaging.phantom.mandible import (
    LABELS,
    MISCH_CLASSES,
    Phantom,
    PhantomInputError,
    _voxelise,
    body_coords,
    bone_sdf_mm,
    canal_distance_mm,
    make_mandible_phantom,
    mandible_hu,
    mandible_labels,
    streak_hu,
)
from ctdrill.imaging.plan.types import DrillSpec
from ctdrill.imaging.sampling.lip import sample_lip_rings
from ctdrill.imaging.volume import CTVolume, SeriesInfo

MISCH_BANDS = {label: (lo, hi) for label, lo, hi in MISCH_BANDS_HU}


@pytest.fixture(scope="module")
def d2() -> Phantom:
    return make_mandible_phantom()


def _down(phantom: Phantom, depth_mm: float) -> np.ndarray:
    """The point ``depth_mm`` below the crest entry along the plan's straight-down axis."""
    return np.asarray(phantom.plan["entry_mm"]) - np.array([0.0, 0.0, depth_mm])


def test_grid_geometry(d2: Phantom) -> None:
    assert d2.hu.shape == (80, 100, 80) and d2.hu.dtype == np.int16
    assert d2.spacing_mm == pytest.approx((0.4, 0.4, 0.4))
    # The field of view is centred on (30, 10, -40) LPS.
    centre = d2.affine_lps @ np.array([79 / 2, 99 / 2, 79 / 2, 1.0])
    np.testing.assert_allclose(centre[:3], [30.0, 10.0, -40.0], atol=1e-9)


@pytest.mark.parametrize("misch", sorted(MISCH_CLASSES))
def test_hu_along_the_planned_axis_is_exact(misch: str) -> None:
    ph = make_mandible_phantom(misch=misch, spacing_mm=1.0)
    g = ph.geometry
    lo, hi = MISCH_BANDS[misch]
    assert lo < g.trabecular_hu < hi
    assert 1500.0 <= g.cortical_hu <= 1800.0
    assert 1.5 <= ph.cortical_thickness_mm <= 2.0
    t_c = ph.cortical_thickness_mm
    canal_top = g.half_height_mm - g.canal_w_mm - g.canal_radius_mm  # depth of the canal roof
    depths = np.array([-5.0, -2.9, -0.1, 0.0, 0.1, t_c - 0.05, t_c + 0.05, 6.0, canal_top - 0.01])
    depths = np.append(depths, [canal_top + 0.01, canal_top + 1.2, canal_top + 2.41, 22.0 - 0.01])
    expected = [-1000, 40, 40, g.cortical_hu, g.cortical_hu, g.cortical_hu, g.trabecular_hu]
    expected += [g.trabecular_hu, g.trabecular_hu, 30, 30, g.trabecular_hu, g.cortical_hu]
    pts = np.stack([_down(ph, float(d)) for d in depths])
    np.testing.assert_array_equal(mandible_hu(pts, g), expected)


def test_signed_distance_of_the_cross_section(d2: Phantom) -> None:
    g = d2.geometry  # half-width 5.5, half-height 11, corner radius 3
    u = np.array([0.0, 0.0, 0.0, 6.5, 5.5, 0.0, 2.5 + 3.0 * np.cos(0.3)])
    w = np.array([11.0, 12.0, 0.0, 0.0, 11.0, -13.0, 8.0 + 3.0 * np.sin(0.3)])
    expected = [0.0, 1.0, -5.5, 1.0, 3.0 * np.sqrt(2.0) - 3.0, 2.0, 0.0]
    np.testing.assert_allclose(bone_sdf_mm(u, w, g), expected, atol=1e-12)


def test_voxels_are_the_field_at_voxel_centres(d2: Phantom) -> None:
    centres = d2.voxel_centres_lps()
    np.testing.assert_array_equal(d2.hu, np.rint(mandible_hu(centres, d2.geometry)))
    counts = np.bincount(mandible_labels(centres, d2.geometry).ravel(), minlength=6)
    assert counts[LABELS["metal"]] == 0
    for name in ("air", "soft_tissue", "cortical", "trabecular", "canal"):
        assert counts[LABELS[name]] > 1000, name


def test_canal_centerline_is_the_canal(d2: Phantom) -> None:
    c = d2.canal_centerline_lps
    assert c.ndim == 2 and c.shape[1] == 3 and c.shape[0] >= 70
    u, w = body_coords(c, d2.geometry)
    np.testing.assert_allclose(canal_distance_mm(u, w, d2.geometry), 0.0, atol=1e-9)
    step = np.linalg.norm(np.diff(c, axis=0), axis=1)
    assert step.max() <= 0.5 + 1e-9
    # It spans the field of view along y (the body's direction at the plan site) ...
    lo = d2.affine_lps[:3, 3]
    hi = d2.affine_lps @ np.array([79, 99, 79, 1.0])
    assert c[:, 1].min() < lo[1] + 0.5 and c[:, 1].max() > hi[1] - 0.5
    assert np.all((c >= lo - 1e-9) & (c <= hi[:3] + 1e-9))
    # ... and the canal is the 30 HU tube of radius 1.2 mm around it.
    assert d2.canal_radius_mm == 1.2
    mid = c[len(c) // 2]
    probe = mid + np.array([[0, 0, 1.19], [0, 0, -1.19], [0, 0, 1.21], [0, 0, -1.21]])
    np.testing.assert_array_equal(mandible_hu(probe, d2.geometry), [30, 30, 1050, 1050])


def test_plan_enters_on_the_crest_and_overshoots_the_margin(d2: Phantom) -> None:
    plan = d2.plan
    assert plan["format"] == "ctdrill-plan/1" and plan["coordinate_system"] == "LPS"
    assert plan["drill"] == {"diameter_mm": 2.0, "tip_length_mm": 0.6, "blades": 2, "rpm": 900}
    assert plan["feed_mm_s"] == 0.4 and plan["margin_mm"] == 2.0
    assert plan["calibration"] == "bone-illustrative"
    (canal,) = plan["landmarks"]
    assert canal["kind"] == "canal" and canal["radius_mm"] == 1.2
    np.testing.assert_array_equal(canal["points_mm"], d2.canal_centerline_lps)
    entry, target = np.array(plan["entry_mm"]), np.array(plan["target_mm"])
    u, w = body_coords(entry, d2.geometry)
    assert float(bone_sdf_mm(u, w, d2.geometry)) == pytest.approx(0.0, abs=1e-12)  # on the crest
    axis = (target - entry) / np.linalg.norm(target - entry)
    np.testing.assert_allclose(axis, [0.0, 0.0, -1.0])

    # Exact clearance: tip at the max safe depth is 2 mm from the canal surface; the planned
    # depth goes deeper (so the export stops on the margin).
    def clearance(depth: float) -> float:
        u, w = body_coords(entry + depth * axis, d2.geometry)
        return float(canal_distance_mm(u, w, d2.geometry)) - d2.canal_radius_mm

    assert clearance(d2.max_safe_depth_mm) == pytest.approx(2.0, abs=1e-12)
    assert d2.max_safe_depth_mm == pytest.approx(10.8)
    planned = float(np.linalg.norm(target - entry))
    assert planned == pytest.approx(12.0) and clearance(planned) < 2.0


def test_noise_is_seeded_gaussian_of_the_given_sigma(d2: Phantom) -> None:
    a = make_mandible_phantom(noise_hu=25.0, seed=3)
    b = make_mandible_phantom(noise_hu=25.0, seed=3)
    c = make_mandible_phantom(noise_hu=25.0, seed=4)
    np.testing.assert_array_equal(a.hu, b.hu)
    assert not np.array_equal(a.hu, c.hu)
    labels = mandible_labels(a.voxel_centres_lps(), a.geometry)
    diff = (a.hu.astype(float) - d2.hu)[labels == LABELS["trabecular"]]
    assert diff.size > 50_000
    assert abs(diff.mean()) < 0.5 and diff.std() == pytest.approx(25.0, rel=0.02)
    assert a.hu.min() >= -1024 and a.hu.max() <= 3071


def test_metal_insert_and_streaks() -> None:
    ph = make_mandible_phantom(metal_streak=True)
    g = ph.geometry
    assert g.metal_xy_lps is not None
    centres = ph.voxel_centres_lps()
    clean = mandible_hu(centres, g)
    streak = streak_hu(centres, g)
    np.testing.assert_array_equal(ph.hu, np.clip(np.rint(clean + streak), -1024, 3071))
    assert (mandible_labels(centres, g) == LABELS["metal"]).sum() > 200
    assert ph.hu.max() == 3071
    # Exact streak values: bright on the lobes (phi = 0), dark between them (phi = pi / 3), 1/r.
    mx, my = g.metal_xy_lps
    z = g.crest_z_mm - 5.0
    pts = np.array(
        [[mx + 4.0, my, z], [mx + 4.0 * np.cos(np.pi / 3), my + 4.0 * np.sin(np.pi / 3), z]]
    )
    np.testing.assert_allclose(streak_hu(pts, g), [200.0, -200.0], atol=1e-9)
    pts[:, 2] = g.crest_z_mm - 12.0  # below the insert: no streak
    np.testing.assert_array_equal(streak_hu(pts, g), [0.0, 0.0])
    # Streaks change the bone in the insert's slices, both ways, but nowhere else.
    bone = clean >= 1000
    assert (ph.hu[bone] > clean[bone] + 50).any() and (ph.hu[bone] < clean[bone] - 50).any()
    below = centres[..., 2] < g.metal_z_range_mm[0]
    np.testing.assert_array_equal(ph.hu[below], clean[below])
    # The planned path keeps clear of the insert.
    entry = np.array(ph.plan["entry_mm"])
    assert np.hypot(entry[0] - mx, entry[1] - my) > 2.0 * g.metal_radius_mm + 3.0


def test_lip_sampling_on_the_phantom_sees_each_layer(d2: Phantom) -> None:
    vol = CTVolume(hu=d2.hu, affine_lps=d2.affine_lps, valid=None, info=SeriesInfo("1.2"))
    entry, target = np.array(d2.plan["entry_mm"]), np.array(d2.plan["target_mm"])
    lip = sample_lip_rings(
        vol,
        entry,
        target,
        np.array([-2.0, 6.0, 11.0]),
        drill=DrillSpec(diameter_mm=2.0, tip_length_mm=0.6),
    )
    assert np.all(lip.hu[0] == 40.0)  # gingiva above the crest
    assert np.all(lip.hu[1] == 1050.0)  # D2 trabecular bone
    assert lip.axis_hu[1] == 1050.0
    assert lip.outside.tolist() == [0, 0, 0]


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"misch": "D7"}, "misch"),
        ({"spacing_mm": 0.0}, "spacing_mm"),
        ({"spacing_mm": float("nan")}, "spacing_mm"),
        ({"noise_hu": -1.0}, "noise_hu"),
        ({"shape": (1, 10, 10)}, "shape"),
        ({"shape": (400, 400, 400)}, "shape"),
        ({"partial_volume": 0}, "partial_volume"),
        ({"partial_volume": 2.5}, "partial_volume"),
    ],
)
def test_bad_parameters_name_the_field(kwargs: dict[str, object], field: str) -> None:
    with pytest.raises(PhantomInputError, match=field):
        make_mandible_phantom(**kwargs)  # type: ignore[arg-type]


def test_a_custom_shape_keeps_the_anatomy_centred() -> None:
    ph = make_mandible_phantom(shape=(20, 30, 40), spacing_mm=0.5)
    assert ph.hu.shape == (20, 30, 40)
    centre = ph.affine_lps @ np.array([39 / 2, 29 / 2, 19 / 2, 1.0])
    np.testing.assert_allclose(centre[:3], [30.0, 10.0, -40.0], atol=1e-9)
    lo = ph.affine_lps[:3, 3]
    hi = (ph.affine_lps @ np.array([39, 29, 19, 1.0]))[:3]
    c = ph.canal_centerline_lps
    assert len(c) >= 20 and np.all((c >= lo - 1e-9) & (c <= hi + 1e-9))
    np.testing.assert_array_equal(ph.hu, np.rint(mandible_hu(ph.voxel_centres_lps(), ph.geometry)))


def test_partial_volume_averages_the_field_over_each_voxel(d2: Phantom) -> None:
    ph = make_mandible_phantom(partial_volume=3)
    assert ph.partial_volume == 3
    centres = d2.voxel_centres_lps()
    offs = np.array([-1.0, 0.0, 1.0]) * 0.4 / 3.0
    mean = np.zeros(d2.hu.shape)
    for dz in offs:
        for dy in offs:
            for dx in offs:
                mean += mandible_hu(centres + np.array([dx, dy, dz]), d2.geometry)
    np.testing.assert_array_equal(ph.hu, np.rint(mean / 27.0))
    # Voxels wholly inside one tissue keep its exact value; edge voxels take in-between values.
    assert (ph.hu == d2.hu).mean() > 0.85
    edge = ph.hu != d2.hu
    assert edge.sum() > 10_000
    assert set(np.unique(ph.hu[edge])) - set(np.unique(d2.hu)) != set()


def test_voxelising_in_slabs_changes_nothing() -> None:
    ph = make_mandible_phantom(spacing_mm=1.0, metal_streak=True)
    whole = _voxelise(ph.hu.shape, ph.affine_lps, ph.geometry, 2)
    slabs = _voxelise(ph.hu.shape, ph.affine_lps, ph.geometry, 2, chunk_voxels=3 * 40 * 32)
    np.testing.assert_array_equal(whole, slabs)


@given(u=st.floats(-12.0, 12.0), w=st.floats(-18.0, 18.0))
def test_signed_distance_matches_a_dense_outline(u: float, w: float) -> None:
    g = make_mandible_phantom(spacing_mm=2.0).geometry
    # The rounded box outline: four straight sides and four quarter circles, densely sampled.
    a, b, rc = g.half_width_mm, g.half_height_mm, g.corner_radius_mm
    t = np.linspace(-1.0, 1.0, 2001)
    sides = [
        np.stack([np.full_like(t, a), t * (b - rc)], 1),
        np.stack([np.full_like(t, -a), t * (b - rc)], 1),
        np.stack([t * (a - rc), np.full_like(t, b)], 1),
        np.stack([t * (a - rc), np.full_like(t, -b)], 1),
    ]
    phi = np.linspace(0.0, 2 * np.pi, 4001)
    for sx in (-1, 1):
        for sy in (-1, 1):
            arc = np.stack([rc * np.cos(phi), rc * np.sin(phi)], 1)
            keep = (arc[:, 0] * sx >= 0) & (arc[:, 1] * sy >= 0)
            sides.append(arc[keep] + [sx * (a - rc), sy * (b - rc)])
    outline = np.concatenate(sides)
    dist = float(np.min(np.hypot(outline[:, 0] - u, outline[:, 1] - w)))
    inside = (
        abs(u) < a
        and abs(w) < b
        and not (
            abs(u) > a - rc
            and abs(w) > b - rc
            and np.hypot(abs(u) - (a - rc), abs(w) - (b - rc)) > rc
        )
    )
    sdf = float(bone_sdf_mm(np.array(u), np.array(w), g))
    assert sdf == pytest.approx(-dist if inside else dist, abs=5e-3)
