"""Plane cuts of the plan's solids against their closed forms (circle, ellipse, band, cone,
tube) and the exact distance to a polyline."""

from __future__ import annotations

import numpy as np
import pytest

from ctdrill.app.gui.sections import (
    Plane,
    cylinder_profile,
    drill_profile,
    near_part,
    polyline_distance_mm,
    revolved_section,
    segments_distance_mm,
    tube_field,
)

AXIAL = Plane(origin_lps=np.zeros(3), u_lps=np.array([1.0, 0, 0]), v_lps=np.array([0, 1.0, 0]))


def _area(poly: np.ndarray) -> float:
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def test_a_cylinder_cut_square_on_is_a_circle_of_its_radius() -> None:
    s, r = cylinder_profile(10.0, 1.5)
    (poly,) = revolved_section(AXIAL, np.array([3.0, 4.0, -5.0]), np.array([0, 0, 1.0]), s, r)
    np.testing.assert_allclose(np.hypot(poly[:, 0] - 3.0, poly[:, 1] - 4.0), 1.5, atol=1e-12)
    # beyond either end the plane misses it
    assert revolved_section(AXIAL, np.array([0, 0, 0.5]), np.array([0, 0, 1.0]), s, r) == []
    assert revolved_section(AXIAL, np.array([0, 0, -10.5]), np.array([0, 0, 1.0]), s, r) == []


@pytest.mark.parametrize("tilt_deg", [10.0, 35.0, 60.0, 80.0])
def test_a_tilted_cylinder_is_an_ellipse_of_semi_axes_r_and_r_over_cos(tilt_deg: float) -> None:
    t = np.deg2rad(tilt_deg)
    axis = np.array([np.sin(t), 0.0, np.cos(t)])
    radius = 1.2
    p0 = -30.0 * axis  # the axis crosses the plane at the origin, 30 mm along it
    s, r = cylinder_profile(60.0, radius)
    (poly,) = revolved_section(AXIAL, p0, axis, s, r)
    a, b = radius / np.cos(t), radius
    np.testing.assert_allclose((poly[:, 0] / a) ** 2 + (poly[:, 1] / b) ** 2, 1.0, atol=1e-9)
    assert poly[:, 0].max() == pytest.approx(a, rel=1e-9)
    assert poly[:, 1].max() == pytest.approx(b, rel=1e-3)
    assert _area(poly) == pytest.approx(np.pi * a * b, rel=5e-3)


def test_a_cylinder_lying_in_the_plane_off_its_axis_is_a_band() -> None:
    axis = np.array([1.0, 0.0, 0.0])
    radius, h = 2.0, 1.2
    s, r = cylinder_profile(15.0, radius)
    (poly,) = revolved_section(AXIAL, np.array([5.0, 7.0, h]), axis, s, r)
    half = np.sqrt(radius**2 - h**2)
    assert (poly[:, 0].min(), poly[:, 0].max()) == pytest.approx((5.0, 20.0))
    np.testing.assert_allclose(np.sort(np.unique(np.round(poly[:, 1], 12))), [7 - half, 7 + half])
    assert _area(poly) == pytest.approx(15.0 * 2 * half, rel=1e-12)
    assert revolved_section(AXIAL, np.array([5.0, 7.0, 2.01]), axis, s, r) == []


def test_the_drill_in_its_own_plane_is_a_band_to_the_cone_tip() -> None:
    axis = np.array([0.0, 1.0, 0.0])
    s, r = drill_profile(12.0, 1.0, 0.6)
    (poly,) = revolved_section(AXIAL, np.zeros(3), axis, s, r)
    assert poly[:, 1].max() == pytest.approx(12.0)  # the tip
    tip = poly[np.argmax(poly[:, 1])]
    assert tip[0] == pytest.approx(0.0, abs=1e-12)
    cone = poly[poly[:, 1] > 11.4]  # on the cone, |u| = r(s) = (12 - s) / 0.6
    np.testing.assert_allclose(np.abs(cone[:, 0]), (12.0 - cone[:, 1]) / 0.6, atol=1e-12)
    body = poly[poly[:, 1] < 11.4]
    np.testing.assert_allclose(np.abs(body[:, 0]), 1.0, atol=1e-12)
    assert _area(poly) == pytest.approx(2.0 * 11.4 + 0.6, rel=1e-12)


def test_a_tapered_body_seen_obliquely_has_its_chords_on_the_cone() -> None:
    # An implant-like taper: radius 2.0 at the platform down to 1.4 at the apex, 10 mm long.
    t = np.deg2rad(40.0)
    axis = np.array([0.0, np.sin(t), -np.cos(t)])
    p0 = np.array([1.0, -2.0, 4.0])
    s_k, r_k = np.array([0.0, 10.0]), np.array([2.0, 1.4])
    polys = revolved_section(AXIAL, p0, axis, s_k, r_k)
    assert len(polys) == 1
    pts = np.column_stack([polys[0], np.zeros(len(polys[0]))])
    rel = pts - p0
    s = rel @ axis
    rho = np.linalg.norm(rel - s[:, None] * axis, axis=1)
    inside_s = (s > 1e-9) & (s < 10 - 1e-9)
    np.testing.assert_allclose(rho[inside_s], np.interp(s[inside_s], s_k, r_k), atol=1e-9)


def test_the_distance_to_a_polyline_is_exact_and_the_tube_field_covers_its_cut() -> None:
    line = np.array([[0.0, 0.0, -5.0], [0.0, 0.0, 5.0], [10.0, 0.0, 5.0]])
    pts = np.array([[3.0, 4.0, 0.0], [0.0, 0.0, -8.0], [5.0, 0.0, 9.0], [12.0, 0.0, 5.0]])
    np.testing.assert_allclose(polyline_distance_mm(pts, line), [5.0, 3.0, 4.0, 2.0])
    field = tube_field(AXIAL, line, reach_mm=2.0, step_mm=0.1)
    assert field is not None
    uu, vv = np.meshgrid(field.u_mm, field.v_mm)
    true = np.hypot(uu, vv)
    exact = true <= 2.0 + 2 * 0.1  # exact up to reach + 2 steps, a lower bound beyond
    np.testing.assert_allclose(field.distance_mm[exact], true[exact], atol=1e-9)
    assert np.all(field.distance_mm[~exact] <= true[~exact])
    assert np.all(field.distance_mm[~exact] >= 2.0 + 2 * 0.1 - 1e-12)
    assert field.u_mm.min() <= -2.0 and field.u_mm.max() >= 2.0
    far = Plane(origin_lps=np.array([0, 0, 7.5]), u_lps=AXIAL.u_lps, v_lps=AXIAL.v_lps)
    assert tube_field(far, line, reach_mm=2.0, step_mm=0.1) is None
    # only the pieces within reach of the plane are kept, clipped to the slab
    np.testing.assert_allclose(near_part(line, AXIAL, 2.0), [[0, 0, -2.0], [0, 0, 2.0]])


def test_a_flat_apex_keeps_its_flat_end() -> None:
    # platform radius 2, apex radius 1.5 with a flat end: the profile steps to 0 at s = 10
    s_k, r_k = np.array([0.0, 10.0, 10.0]), np.array([2.0, 1.5, 0.0])
    (poly,) = revolved_section(AXIAL, np.zeros(3), np.array([0.0, 1.0, 0.0]), s_k, r_k)
    end = poly[np.isclose(poly[:, 1], 10.0)]
    np.testing.assert_allclose(np.sort(end[:, 0]), [-1.5, 1.5], atol=1e-12)
    start = poly[np.isclose(poly[:, 1], 0.0)]
    np.testing.assert_allclose(np.sort(start[:, 0]), [-2.0, 2.0], atol=1e-12)
    assert _area(poly) == pytest.approx(10.0 * (2.0 + 1.5), rel=1e-12)  # a trapezoid


def test_the_vectorised_segment_distance_equals_the_polyline_distance() -> None:
    rng = np.random.default_rng(7)
    line = np.cumsum(rng.normal(size=(30, 3)), axis=0) + np.array([0.0, 100.0, 700.0])
    pts = line.mean(axis=0) + rng.normal(scale=6.0, size=(500, 3))
    want = polyline_distance_mm(pts, line)
    got = segments_distance_mm(pts, line[:-1], line[1:], chunk=128)
    np.testing.assert_allclose(got, want, atol=1e-9)
