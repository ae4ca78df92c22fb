"""Teeth are not bone: a crown against the plate is not wall, the crest is the bone's not the
crown's, an implant in a tooth is refused and its distance to a neighbouring root reported."""

from __future__ import annotations

import numpy as np
import pytest

from ctdrill.engine.implant import implant_outcome
from ctdrill.engine.implant_facts import crest_depth_mm
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.provenance import SeriesInfo
from ctdrill.imaging.teeth import TOOTH_HU, TOOTH_SLAB, is_bone_hu, tooth_points_lps
from ctdrill.imaging.volume import CTVolume
from tests.imaging.test_walls_envelope import OUTER, PARALLEL, SP, _jaw, _plan


def _with(vol: CTVolume, box: tuple[tuple[float, float], ...], hu: float) -> CTVolume:
    """``vol`` with the voxels whose centres lie in ``box`` ((x0, x1), (y0, y1), (z0, z1)) set
    to ``hu``."""
    a = vol.affine_lps
    k, j, i = (np.arange(n) for n in vol.hu.shape)
    x, y, z = a[0, 3] + SP * i, a[1, 3] + SP * j, a[2, 3] + SP * k
    zz, yy, xx = np.meshgrid(z, y, x, indexing="ij")
    (x0, x1), (y0, y1), (z0, z1) = box
    inside = (xx > x0) & (xx < x1) & (yy > y0) & (yy < y1) & (zz > z0) & (zz < z1)
    out = np.array(vol.hu)
    out[inside] = hu
    return CTVolume(out, vol.affine_lps, None, vol.info)


def test_the_threshold() -> None:
    assert is_bone_hu(np.array([100.0, 150.0, 1800.0, TOOTH_HU, 3000.0, np.nan])).tolist() == [
        False, True, True, False, False, False,
    ]  # fmt: skip


def test_enamel_against_the_plate_is_not_wall() -> None:
    # a crown (2600 HU) pressed against the buccal (+x) face of the jaw, 3 mm thick
    vol = _with(_jaw(300.0), ((OUTER, OUTER + 3.0), (-6.0, 6.0), (-12.0, 1.0)), 2600.0)
    out = implant_outcome(vol, _plan())
    assert out is not None and out.walls.buccal_mm is not None
    assert out.walls.buccal_mm == pytest.approx(OUTER - PARALLEL.diameter_mm / 2, abs=0.3)


def test_the_crest_is_the_bones_not_the_crowns() -> None:
    # an immediate implant through a crown standing 4 mm on the crest (jaw top at z = 1)
    vol = _with(_jaw(300.0), ((-3.0, 3.0), (-3.0, 3.0), (1.0, 5.0)), 2600.0)
    plan = Plan([0.0, 0.0, 7.0], [0.0, 0.0, -10.0], implant=PARALLEL)
    crest = crest_depth_mm(vol, plan, 17.0)
    assert crest == pytest.approx(6.0, abs=0.5)  # z = 1 to a voxel, not the crown top (z = 5)


def test_an_implant_in_a_tooth_is_refused_and_a_root_nearby_is_measured() -> None:
    base = _jaw(300.0)
    inside = _with(base, ((-1.5, 1.5), (-1.5, 1.5), (-9.0, 0.5)), 2200.0)  # a root at the site
    out = implant_outcome(inside, _plan())
    assert out is not None and out.tooth_mm is not None and out.tooth_mm < 0.0
    assert "implant_in_tooth" in out.codes
    # a neighbouring root 3 mm from the axis (mesial, +y): 0.95 mm from the 2.05 mm body
    near = _with(base, ((-2.0, 2.0), (3.0, 8.0), (-9.0, 0.5)), 2200.0)
    out = implant_outcome(near, _plan())
    nearest = np.hypot(3.0 + SP / 2, SP / 2)  # the nearest voxel centre inside the box
    assert out is not None and out.tooth_mm == pytest.approx(nearest - 2.05, abs=1e-6)
    assert "implant_near_tooth" in out.codes and "implant_in_tooth" not in out.codes
    far = implant_outcome(_with(base, ((-2.0, 2.0), (6.0, 9.0), (-9.0, 0.5)), 2200.0), _plan())
    assert far is not None and far.tooth_mm is not None and far.tooth_mm > 1.5
    assert "implant_near_tooth" not in far.codes
    assert implant_outcome(base, _plan()).tooth_mm is None  # type: ignore[union-attr]
    assert len(tooth_points_lps(base)) == 0


@pytest.mark.parametrize("dtype", [np.int16, np.float32])
def test_tooth_points_are_the_float64_rules_voxels_slab_by_slab(dtype: type) -> None:
    """The tooth voxels found slab by slab, compared in the voxels' own type, are those of the
    float64 comparison over the whole volume, in its order (values just below, at and above
    the threshold, NaN, padding, a last slab shorter than the others)."""
    rng = np.random.default_rng(7)
    shape = (2 * TOOTH_SLAB + 5, 9, 11)
    hu = (rng.random(shape) * 4000.0 - 1000.0).astype(dtype)
    hu[0, 0, :3] = [TOOTH_HU - 1.0, TOOTH_HU, TOOTH_HU + 1.0]
    if dtype == np.float32:
        hu[1, 0, :3] = [np.nextafter(np.float32(TOOTH_HU), np.float32(0.0)), TOOTH_HU, np.nan]
    affine = np.diag([0.3, 0.4, 0.5, 1.0])
    affine[:3, 3] = [1.0, -2.0, 3.0]
    for valid in (None, rng.random(shape) > 0.2):
        volume = CTVolume(hu=hu, affine_lps=affine, valid=valid, info=SeriesInfo("1.2"))
        mask = np.asarray(hu, dtype=np.float64) >= TOOTH_HU
        if volume.valid is not None:
            mask &= volume.valid
        k, j, i = np.nonzero(mask)
        expected = (affine @ np.stack([i, j, k, np.ones_like(i)]).astype(np.float64))[:3].T
        np.testing.assert_array_equal(tooth_points_lps(volume), expected)
