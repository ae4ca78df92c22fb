"""Walls to the jaw's surface: an intact cortex around cancellous bone of any density (D4 and
fatty marrow included) gives the true walls; leaving the envelope is the perforation."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from ctdrill.imaging.plan.implants import ImplantSpec
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.provenance import SeriesInfo
from ctdrill.imaging.sampling.wall_warnings import bone_wall_warnings
from ctdrill.imaging.sampling.walls import plan_bone_walls
from ctdrill.imaging.volume import CTVolume

SP = 0.25
PARALLEL = ImplantSpec("parallel 4.1 x 10", 4.1, 10.0, 4.1, "flat")
#: the jaw's outer half-width, the cortex thickness: true walls 5.25 - 2.05 = 3.2 mm
OUTER, CORTEX = 5.25, 1.0
ARCH = np.array([[-60.0 + 60.0 * math.cos(a), 60.0 * math.sin(a), -6.0] for a in (-0.4, 0.0, 0.4)])


def _jaw(
    cancellous_hu: float, *, cortical_hu: float = 1500.0, air_pocket: bool = False
) -> CTVolume:
    """A jaw slab |x| <= OUTER, z in [-20, 1], cortex CORTEX thick on every face, cancellous
    inside, soft tissue (40 HU) 3 mm beyond the faces, air further; each voxel the value of its
    centre (no partial volume)."""
    xs = np.arange(-12.0, 12.0 + 1e-9, SP) + SP / 2
    ys = np.arange(-16.0, 16.0 + 1e-9, SP) + SP / 2
    zs = np.arange(-24.0, 5.0 + 1e-9, SP) + SP / 2
    z, _y, x = np.meshgrid(zs, ys, xs, indexing="ij")
    top, bottom = 1.0, -20.0
    inside_d = np.minimum.reduce([OUTER - np.abs(x), top - z, z - bottom])  # depth into the jaw
    hu = np.full(x.shape, -1000.0)
    hu[inside_d > -3.0] = 40.0
    hu[inside_d >= 0.0] = cortical_hu
    hu[inside_d >= CORTEX] = cancellous_hu
    if air_pocket:  # an air cell (a sinus) lined by 0.5 mm of cortex, 2.5-3.5 mm out (+x)
        cell = (z < -2.0) & (z > -15.0)
        hu[cell & (x > 2.5) & (x < 3.0)] = cortical_hu
        hu[cell & (x > 3.0) & (x < 3.5)] = -900.0
    aff = np.eye(4)
    aff[:3, :3] *= SP
    aff[:3, 3] = [xs[0], ys[0], zs[0]]
    return CTVolume(hu.astype(np.float32), aff, None, SeriesInfo("1.2.826.0.1.3680043.2.1125.2"))


def _plan(x_mm: float = 0.0) -> Plan:
    return Plan([x_mm, 0.0, 0.5], [x_mm, 0.0, -10.0], implant=PARALLEL, arch_lps=ARCH)


@pytest.mark.parametrize("cancellous_hu", [-80.0, 50.0, 100.0, 140.0, 300.0, 1000.0])
def test_intact_cortices_give_the_true_walls_at_any_cancellous_density(
    cancellous_hu: float,
) -> None:
    walls = plan_bone_walls(_jaw(cancellous_hu), _plan(), n_angles=24)
    assert walls is not None and walls.unknown_fraction == 0.0
    true = OUTER - PARALLEL.diameter_mm / 2  # 3.2 mm
    assert walls.min_mm == pytest.approx(true, abs=0.3)
    assert walls.buccal_mm == pytest.approx(true, abs=0.3)
    assert walls.lingual_mm == pytest.approx(true, abs=0.3)
    assert walls.perforation is None
    codes = [w.code for w in bone_wall_warnings(walls, min_wall_mm=1.5, label="p")]
    assert codes == []


@pytest.mark.parametrize("cancellous_hu", [50.0, 1000.0])
def test_leaving_the_envelope_is_the_perforation(cancellous_hu: float) -> None:
    # the body 4.1 mm wide centred 4.5 mm out: its +x side stands 1.3 mm beyond the jaw's face
    walls = plan_bone_walls(_jaw(cancellous_hu), _plan(4.5), n_angles=24)
    assert walls is not None and walls.perforation is not None
    assert walls.perforation.direction_lps[0] > 0.9
    assert walls.min_mm == 0.0
    codes = [w.code for w in bone_wall_warnings(walls, min_wall_mm=1.5, label="p")]
    assert codes == ["thin_wall", "cortical_perforation"]


def test_air_is_never_inside_the_jaw() -> None:
    walls = plan_bone_walls(_jaw(100.0, air_pocket=True), _plan(), n_angles=24)
    assert walls is not None
    # buccal (+x): the jaw ends at the air cell's lining 3 mm out, 0.95 mm from the surface
    assert walls.buccal_mm == pytest.approx(3.0 - 2.05, abs=0.3)
    assert walls.lingual_mm == pytest.approx(OUTER - 2.05, abs=0.3)


def test_without_an_arch_the_jaw_direction_comes_from_the_walls() -> None:
    vol = _jaw(50.0)
    centred = plan_bone_walls(vol, Plan([0.0, 0, 0.5], [0.0, 0, -10.0], implant=PARALLEL))
    assert centred is not None and centred.perforation is None
    assert centred.min_mm == pytest.approx(OUTER - 2.05, abs=0.3)
    out = plan_bone_walls(vol, Plan([4.5, 0, 0.5], [4.5, 0, -10.0], implant=PARALLEL))
    assert out is not None and out.perforation is not None and out.min_mm == 0.0


def test_an_apex_in_the_canal_is_named_as_the_canal_not_a_perforation() -> None:
    from ctdrill.imaging.plan.implant_safety import implant_clearance, implant_margin_warnings
    from ctdrill.imaging.plan.landmarks import CanalLandmark

    vol = _jaw(100.0)
    # a soft canal (radius 1.2 mm) along y, its centre 0.5 mm under the apex (z = -10)
    xs = vol.affine_lps[0, 3] + SP * np.arange(vol.hu.shape[2])
    zs = vol.affine_lps[2, 3] + SP * np.arange(vol.hu.shape[0])
    zz, xx = np.meshgrid(zs, xs, indexing="ij")
    tube = (xx**2 + (zz + 10.5) ** 2) <= 1.2**2
    hu = np.array(vol.hu)
    hu[tube[:, None, :].repeat(hu.shape[1], axis=1)] = 30.0
    vol = CTVolume(hu, vol.affine_lps, None, vol.info)
    canal = CanalLandmark(
        "IAN canal", np.array([[0.0, -15.0, -10.5], [0.0, 15.0, -10.5]]), radius_mm=1.2
    )
    plan = replace(_plan(), landmarks=(canal,))
    walls = plan_bone_walls(vol, plan, n_angles=24)
    assert walls is not None and walls.perforation is None
    codes = [w.code for w in implant_margin_warnings(plan, implant_clearance(plan))]
    assert codes == ["implant_violates_margin", "canal_entry"]
    ((msg,),) = [
        [
            w.message
            for w in implant_margin_warnings(plan, implant_clearance(plan))
            if w.code == "canal_entry"
        ]
    ]
    assert "'IAN canal'" in msg and "0.70 mm into it" in msg
