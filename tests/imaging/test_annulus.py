"""Rings on the part of the lip outside earlier holes (imaging.sampling.annulus), checked
against the hole's definition point by point and against a brute-force measure."""

from __future__ import annotations

import numpy as np
import pytest

from ctdrill.imaging.sampling.annulus import Hole, HoleInputError, annulus_rings
from ctdrill.imaging.sampling.lip import ring_radii_mm


def _in_hole(r: np.ndarray, xi: np.ndarray, hole: Hole) -> np.ndarray:
    """The hole's definition: inside the drill solid swept to its reached depth."""
    b = hole.tip_length_mm / hole.radius_mm
    return (r < hole.radius_mm) & (xi < hole.depth_mm - b * r)


def test_without_holes_the_rings_are_the_full_lip() -> None:
    depth = np.linspace(0.0, 5.0, 11)
    radii, weights = annulus_rings(1.4, 0.84, depth, (), 6)
    np.testing.assert_allclose(radii, np.broadcast_to(ring_radii_mm(2.8, 6), (11, 6)), rtol=1e-15)
    np.testing.assert_allclose(weights, 1.0 / 6, rtol=1e-15)


@pytest.mark.parametrize("seed", range(5))
def test_rings_avoid_every_hole_and_weigh_the_cut_share(seed: int) -> None:
    rng = np.random.default_rng(seed)
    radius, tip = 1.75, float(rng.uniform(0.0, 2.0))
    holes = tuple(
        Hole(float(rng.uniform(0.3, 1.6)), float(rng.uniform(0.0, 1.5)), float(rng.uniform(2, 6)))
        for _ in range(3)
    )
    depth = np.linspace(0.0, 8.0, 81)
    n = 7
    radii, weights = annulus_rings(radius, tip, depth, holes, n)
    xi = depth[:, None] - tip * radii / radius
    for hole in holes:
        assert not np.any(_in_hole(radii, xi, hole))
    assert np.all((radii >= 0.0) & (radii <= radius))
    assert np.all(np.diff(radii, axis=1) > 0.0)
    # the cut share by brute force: 100 000 points along the lip
    r = (np.arange(100_000) + 0.5) / 100_000 * radius
    xi_f = depth[:, None] - tip * r / radius
    held = np.zeros(xi_f.shape, dtype=bool)
    for hole in holes:
        held |= _in_hole(r[None, :], xi_f, hole)
    share = 1.0 - held.mean(axis=1)
    np.testing.assert_allclose(weights.sum(axis=1), share, atol=1e-4)
    np.testing.assert_allclose(weights, weights[:, :1] * np.ones((1, n)))
    # every ring sits mid-way in arc length: equal cut measure between neighbours
    for d in range(0, depth.size, 10):
        inside = ~held[d]
        arc = np.cumsum(inside) * (radius / r.size)
        at = np.interp(radii[d], r, arc)
        np.testing.assert_allclose(at, (np.arange(n) + 0.5) * arc[-1] / n, atol=5e-5)


def test_a_hole_no_drill_leaves_is_refused() -> None:
    with pytest.raises(HoleInputError, match="radius_mm"):
        Hole(0.0, 0.6, 3.0)
    with pytest.raises(HoleInputError, match="depth_mm"):
        Hole(1.0, 0.6, float("nan"))
