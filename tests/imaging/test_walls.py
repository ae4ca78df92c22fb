"""Bone walls around the implant on closed-form phantoms.

The phantoms' CT numbers are linear in the distance to the bone's faces near them
(``HU = 150 + G * distance inside``), and trilinear interpolation reproduces a linear
function exactly, so the 150 HU edge that the walls follow is exactly the geometric face: the
walls have closed forms (half-width less the radius, ...), up to the bisection tolerance.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from ctdrill.imaging.misch import BONE_HU
from ctdrill.imaging.plan.implants import ImplantSpec, implant_placement
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.provenance import SeriesInfo
from ctdrill.imaging.sampling.arch import buccal_normal_lps
from ctdrill.imaging.sampling.wall_warnings import bone_wall_warnings
from ctdrill.imaging.sampling.walls import (
    BISECT_TOL_MM,
    PERFORATION_DEPTH_MM,
    bone_walls,
    plan_bone_walls,
)
from ctdrill.imaging.volume import CTVolume

SP = 0.4
G = 400.0  # HU per mm inside the bone
PARALLEL = ImplantSpec("parallel 4.1 x 10", 4.1, 10.0, 4.1, "flat")
TAPERED = ImplantSpec("tapered 4.1 x 10", 4.1, 10.0, 2.9, "round")
#: An arc of the arch, its centre 60 mm lingual (-x) of the implants: buccal is +x there.
ARCH = np.array([[-60.0 + 60.0 * math.cos(a), 60.0 * math.sin(a), -6.0] for a in (-0.4, 0.0, 0.4)])


def _slab(
    half_width: float, *, top_z: float = 50.0, half: float = 18.0, z_range=(-22.0, 4.0)
) -> CTVolume:
    """Bone where ``|x| <= half_width`` (and below ``top_z``), HU linear in the distance to
    the nearest face near it (clipped far from the faces)."""
    xs = np.arange(-half, half + 1e-9, SP)
    zs = np.arange(z_range[0], z_range[1] + 1e-9, SP)
    z, _y, x = np.meshgrid(zs, xs, xs, indexing="ij")
    inside = np.minimum(half_width - np.abs(x), top_z - z)
    hu = np.clip(BONE_HU + G * inside, -1000.0, 1900.0).astype(np.float32)  # below teeth
    aff = np.eye(4)
    aff[:3, :3] *= SP
    aff[:3, 3] = [xs[0], xs[0], zs[0]]
    return CTVolume(hu, aff, None, SeriesInfo("1.2.826.0.1.3680043.2.1125.1"))


def _plan(spec: ImplantSpec, x_mm: float = 0.0, tilt_deg: float = 0.0, **kw: object) -> Plan:
    """Entry at (x, 0, 0); the axis tilted towards +x by ``tilt_deg``; apex 11 mm down it."""
    t = math.radians(tilt_deg)
    u = np.array([math.sin(t), 0.0, -math.cos(t)])
    entry = np.array([x_mm, 0.0, 0.0])
    return Plan(entry, entry + 11.0 * u, implant=spec, **kw)


def test_implant_in_a_slab_walls_are_the_half_width_less_the_radius() -> None:
    vol = _slab(4.0)
    for x in (0.0, 0.7, -0.5):
        plan = _plan(PARALLEL, x, arch_lps=ARCH)
        walls = plan_bone_walls(vol, plan, max_wall_mm=5.0)
        assert walls is not None
        buccal, lingual = 4.0 - x - 2.05, 4.0 + x - 2.05
        assert walls.buccal_mm == pytest.approx(buccal, abs=BISECT_TOL_MM)
        assert walls.lingual_mm == pytest.approx(lingual, abs=BISECT_TOL_MM)
        assert walls.min_mm == pytest.approx(min(buccal, lingual), abs=BISECT_TOL_MM)
        side = 1.0 if buccal <= lingual else -1.0
        np.testing.assert_allclose(walls.direction_lps, [side, 0.0, 0.0], atol=1e-12)
        assert walls.perforation is None and walls.unknown_fraction == 0.0
        assert not walls.capped
        np.testing.assert_allclose(walls.buccal_lps, [1.0, 0.0, 0.0], atol=1e-12)
        codes = [w.code for w in bone_wall_warnings(walls, min_wall_mm=1.5, label="p")]
        assert codes == ([] if min(buccal, lingual) >= 1.5 else ["thin_wall"])
    # a tapered body: the wall grows as the body narrows; the thinnest at the platform
    walls = bone_walls(vol, implant_placement(_plan(TAPERED)), max_wall_mm=5.0)  # type: ignore[arg-type]
    assert walls.min_mm == pytest.approx(4.0 - 2.05, abs=BISECT_TOL_MM)
    assert walls.below_platform_mm == 0.0 and walls.depth_mm == pytest.approx(1.0)
    k = int(np.argmin(np.abs(walls.depth_grid_mm - 6.0)))  # 5 mm below the platform
    r = TAPERED.radius_at_mm(5.0)
    assert np.nanmin(walls.wall_mm[k]) == pytest.approx(4.0 - r, abs=BISECT_TOL_MM)
    assert walls.buccal_mm is None and walls.lingual_mm is None  # no arch


def test_thin_wall_names_the_thinnest_wall_and_where() -> None:
    plan = _plan(PARALLEL, 0.95, arch_lps=ARCH, name="36")
    walls = plan_bone_walls(_slab(3.5), plan, max_wall_mm=5.0)
    assert walls is not None and walls.min_mm == pytest.approx(0.5, abs=BISECT_TOL_MM)
    (warning,) = bone_wall_warnings(walls, min_wall_mm=1.5, label="plan '36'")
    code, msg = warning.code, warning.message
    assert code == "thin_wall"
    assert msg.startswith("plan '36': the thinnest bone wall around the implant is 0.5 mm")
    assert "towards buccal (" in msg and "buccal 0.5 mm, lingual 2.4 mm" in msg
    assert bone_wall_warnings(walls, min_wall_mm=0.5, label="x") == []


def test_a_tilted_implant_leaving_the_slab_perforates_where_the_closed_form_says() -> None:
    tilt = 20.0
    plan = _plan(PARALLEL, 0.0, tilt, arch_lps=ARCH)
    place = implant_placement(plan)
    assert place is not None
    walls = plan_bone_walls(_slab(4.0), plan, max_wall_mm=5.0)
    assert walls is not None and walls.perforation is not None
    a = math.radians(tilt)
    # the ring's outermost point, platform_x + s sin(a) + R cos(a), reaches the face x = 4
    s_star = (4.0 - place.platform_lps[0] - 2.05 * math.cos(a)) / math.sin(a)
    assert PERFORATION_DEPTH_MM < s_star < PARALLEL.length_mm
    p = walls.perforation
    assert s_star <= p.below_platform_mm[0] <= s_star + 0.25 + 1e-9  # the depth step
    assert p.below_platform_mm[1] == pytest.approx(PARALLEL.length_mm)  # to the apex face
    assert p.depth_mm[0] == pytest.approx(place.platform_depth_mm + p.below_platform_mm[0])
    np.testing.assert_allclose(p.direction_lps, [math.cos(a), 0.0, math.sin(a)], atol=0.02)
    assert p.point_lps[0] >= 4.0
    assert walls.min_mm == 0.0 and walls.buccal_mm == 0.0
    # lingually the thinnest wall is at the platform, along the ray tilted with the axis
    lingual = (4.0 + place.platform_lps[0]) / math.cos(a) - 2.05
    assert walls.lingual_mm == pytest.approx(lingual, abs=BISECT_TOL_MM)
    codes = [w.code for w in bone_wall_warnings(walls, min_wall_mm=1.5, label="p")]
    assert codes == ["thin_wall", "cortical_perforation"]
    # the same tilt the other way stays in bone longer (the slab is centred on the entry)
    assert plan_bone_walls(_slab(8.0), plan, max_wall_mm=5.0).perforation is None  # type: ignore[union-attr]


def test_a_platform_above_the_crest_is_not_a_perforation_but_a_thin_wall() -> None:
    # bone below z = top; the platform at z = -1 (entry at 0, 11 mm path, 10 mm implant)
    for above, perforates in ((0.8, False), (1.4, True)):
        vol = _slab(5.0, top_z=-1.0 - above)
        walls = plan_bone_walls(vol, _plan(PARALLEL), max_wall_mm=5.0)
        assert walls is not None
        assert walls.min_mm == 0.0 and walls.below_platform_mm == 0.0
        assert (walls.perforation is not None) == perforates
        if walls.perforation is not None:
            lo, hi = walls.perforation.below_platform_mm
            assert PERFORATION_DEPTH_MM < lo <= above and hi <= above


def test_outside_the_ct_is_unknown_never_bone() -> None:
    # bone reaches the CT's border at x = 7.2: rays towards it leave the CT inside bone
    vol = _slab(30.0, half=7.2)
    walls = plan_bone_walls(vol, _plan(PARALLEL, arch_lps=ARCH), max_wall_mm=8.0)
    assert walls is not None
    assert 0.0 < walls.unknown_fraction < 1.0
    # only the diagonal rays reach the 8 mm cap inside the square CT: at least 8 mm of bone
    assert walls.min_mm == pytest.approx(8.0) and walls.capped
    assert walls.buccal_mm == pytest.approx(8.0)
    assert np.isnan(walls.wall_mm).any()
    codes = [w.code for w in bone_wall_warnings(walls, min_wall_mm=1.5, label="p")]
    assert codes == ["bone_walls_unknown"]
    # the implant partly above the CT: its surface there is neither bone nor a perforation
    high = _slab(5.0, z_range=(-22.0, -6.0))
    walls = plan_bone_walls(high, _plan(PARALLEL), max_wall_mm=5.0)
    assert walls is not None and walls.perforation is None
    assert walls.min_mm == pytest.approx(5.0 - 2.05, abs=BISECT_TOL_MM)
    assert np.isnan(walls.wall_mm[0]).all() and walls.unknown_fraction > 0.3


def test_the_buccal_normal_points_out_of_the_arch() -> None:
    n = buccal_normal_lps(ARCH, np.array([0.0, 0.0, -3.0]))
    assert n is not None
    np.testing.assert_allclose(n, [1.0, 0.0, 0.0], atol=1e-9)
    reverse = buccal_normal_lps(ARCH[::-1], np.array([0.0, 0.0, -3.0]))
    np.testing.assert_allclose(reverse, n, atol=1e-9)  # whichever way it was drawn
    straight = np.array([[0.0, -20.0, 0.0], [0.0, 20.0, 0.0]])
    assert buccal_normal_lps(straight, np.zeros(3)) is None
    assert buccal_normal_lps(ARCH, np.array([0.0, 80.0, 0.0])) is None  # beyond its ends


def test_without_an_arch_the_direction_is_in_patient_axes() -> None:
    walls = plan_bone_walls(_slab(3.5), _plan(PARALLEL, 0.95), max_wall_mm=5.0)
    assert walls is not None
    (warning,) = bone_wall_warnings(walls, min_wall_mm=1.5, label="p")
    msg = warning.message
    assert "towards L 1.00" in msg
