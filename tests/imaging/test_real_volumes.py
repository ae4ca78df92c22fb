"""Real anatomy from files: the VTK head CT (NIfTI) and a CT synthesised in a real mandible.

``../shared/data/vtk_headsq_quarter/headsq_quarter.nii.gz`` is a real head CT (orbits to below
the chin, teeth, the whole mandible) at 3.2 x 3.2 x 1.5 mm: the loader must read it exactly
(nibabel is the reference), and the arch, the panoramic and a plan must work on its mandible.
``tests/imaging/real_mandible.py`` builds a CT inside a real mandible segmentation (TCIA): its
arch, canals and bone are known, so a drill over the canal stops where a closed-form distance
says.
"""

from __future__ import annotations

import math
from pathlib import Path

import nibabel
import numpy as np
import pytest

from ctdrill.imaging import load_ct
from ctdrill.imaging.plan.landmarks import CanalLandmark
from ctdrill.imaging.plan.safety import safe_depth
from ctdrill.imaging.plan.types import DrillSpec, Plan
from ctdrill.imaging.sampling.lip import sample_lip_rings
from ctdrill.imaging.sampling.reformat import panorama
from ctdrill.imaging.volume import CTVolume
from tests.conftest import SHARED_DATA
from tests.imaging.real_mandible import RealMandible, real_mandible
from tests.imaging.volume_writers import FLIP, write_mha, write_nifti

HEAD = SHARED_DATA / "vtk_headsq_quarter" / "headsq_quarter.nii.gz"
#: Bone, HU (above soft tissue and the canal's contents, below cortical and trabecular bone).
BONE_HU = 300.0
#: The axial slice of the head's mandible body the arch is fitted on (z = -115.5 mm).
HEAD_ARCH_SLICE = 77


@pytest.fixture(scope="module")
def head() -> CTVolume:
    return load_ct(HEAD)


def test_head_ct_loads_exactly(head: CTVolume) -> None:
    img = nibabel.load(str(HEAD))
    np.testing.assert_array_equal(head.hu, np.asarray(img.dataobj).transpose(2, 1, 0))
    assert head.hu.dtype == np.int16  # int16 stored, scl_inter -1024: exact in int16
    np.testing.assert_allclose(head.affine_lps, FLIP @ img.affine, rtol=0, atol=0)
    assert head.dims == (64, 64, 93)
    np.testing.assert_allclose(head.spacing_mm, (3.2, 3.2, 1.5), rtol=1e-7)
    assert (int(head.hu.min()), int(head.hu.max())) == (-1024, 2902)
    assert head.info.is_hu and head.info.source_format == "NIfTI-1"
    # 3.2 x 3.2 x 1.5 mm voxels limit every clearance (imaging/resolution.py): said so
    assert head.warning_codes == ("coarse_voxels",)
    (coarse,) = head.warnings
    assert "3.2" in coarse.message
    # i to the patient's left, j posterior, k inferior (SOURCE.txt)
    assert head.affine_lps[0, 0] > 0 and head.affine_lps[1, 1] > 0 and head.affine_lps[2, 2] < 0


def _head_arch(volume: CTVolume) -> np.ndarray:
    """A parabola through the mandible's bone voxels on one axial slice (the spine left out)."""
    k = HEAD_ARCH_SLICE
    _, jj, ii = np.nonzero(volume.hu[k : k + 1] > BONE_HU)
    front = jj < 36  # the cervical spine lies behind row 36
    pts = volume.index_to_lps(
        np.stack([ii[front], jj[front], np.full(front.sum(), k)], 1).astype(float)
    )
    coef = np.polyfit(pts[:, 0], pts[:, 1], 2)
    xs = np.linspace(pts[:, 0].min() + 3.0, pts[:, 0].max() - 3.0, 25)
    return np.stack([xs, np.polyval(coef, xs), np.full(xs.size, pts[0, 2])], 1)


def test_head_arch_and_panoramic(head: CTVolume) -> None:
    arch = _head_arch(head)
    assert arch[0, 2] == pytest.approx(-115.5)
    on_bone = head.sample(arch) > BONE_HU
    assert on_bone.mean() >= 0.9
    pano = panorama(head, arch, slab_mm=6.0)
    assert pano.column_letters == ("R", "L")
    z = pano.lps[:, 0, 2]
    row = lambda z_mm: int(np.argmin(np.abs(z - z_mm)))  # noqa: E731
    # the mandible's body is bone right across the image; the teeth above it are brighter
    assert (pano.hu[row(-117.0)] > BONE_HU).mean() >= 0.95
    assert (pano.hu[row(-90.0)] > 1500).any()
    # the nasal cavity and sinuses (air) above the palate
    assert (pano.hu[row(-36.0)] < -200).mean() > 0.3


def test_a_plan_on_the_head_mandible(head: CTVolume) -> None:
    arch = _head_arch(head)
    site = arch[6]  # patient's right premolar region
    column = np.array([[site[0], site[1], z] for z in np.arange(site[2], site[2] + 30, 0.25)])
    crest_z = column[np.argmax(head.sample(column) < BONE_HU), 2]
    entry = np.array([site[0], site[1], crest_z + 1.0])
    target = entry - [0.0, 0.0, 12.0]
    depth = np.arange(0.0, 12.0001, 0.25)
    lip = sample_lip_rings(head, entry, target, depth, DrillSpec())
    assert lip.outside.sum() == 0
    assert np.all(lip.axis_hu[depth >= 2.0] > BONE_HU)  # the drill runs in the mandible
    assert lip.axis_hu[0] < BONE_HU  # and starts above the crest


# --------------------------------------------------------------------------- real mandible


@pytest.fixture(scope="module")
def mandible() -> RealMandible:
    return real_mandible()


def test_synthetic_ct_follows_the_real_mandible(mandible: RealMandible) -> None:
    m = mandible
    hu = m.volume.hu.astype(np.float64)
    deep = m.depth_mm > m.cortical_mm + 1.0
    canal_free = np.ones_like(deep)
    for line in m.canals_lps:
        idx = m.volume.lps_to_index(line)
        lo = np.floor(idx.min(0) - 4).astype(int)
        hi = np.ceil(idx.max(0) + 4).astype(int)
        canal_free[lo[2] : hi[2], lo[1] : hi[1], lo[0] : hi[0]] = False
    assert abs(hu[deep & canal_free].mean() - m.trabecular_hu) < 2.0
    shell = m.bone & (m.depth_mm <= m.cortical_mm)
    assert abs(hu[shell].mean() - m.cortical_hu) < 2.0
    # resampling keeps the real bone's volume (18604 voxels of 0.98 x 0.98 x 2.5 mm)
    real_ml = 18604 * 0.98 * 0.98 * 2.5 / 1000
    ours_ml = m.bone.sum() * 0.75**3 / 1000
    assert ours_ml == pytest.approx(real_ml, rel=0.05)


def test_arch_and_canals_lie_in_the_body(mandible: RealMandible) -> None:
    m = mandible
    v = m.volume
    assert (v.sample(m.arch_lps) > BONE_HU).mean() >= 0.85
    length = np.linalg.norm(np.diff(m.arch_lps[:, :2], axis=0), axis=1).sum()
    assert 120.0 < length < 220.0  # an adult mandible's arch, mm
    for line in m.canals_lps:
        inside = v.lps_to_index(line)
        depth = np.array([m.depth_mm[tuple(np.rint(p[::-1]).astype(int))] for p in inside])
        assert depth.min() >= m.canal_radius_mm + 0.5
        assert np.abs(v.sample(line) - 30.0).max() < 100.0  # the canal's contents, with noise
    # the panoramic along the arch shows the body as bone and the canals as darker
    pano = panorama(v, m.arch_lps, slab_mm=2.0)
    assert pano.inside_fraction == 1.0


def test_drill_over_a_real_canal_stops_on_the_margin(mandible: RealMandible) -> None:
    m = mandible
    canal = m.canals_lps[0]
    over = canal[len(canal) // 2]
    entry = over + np.array([0.0, 0.0, 16.0])
    target = over - np.array([0.0, 0.0, 2.0])
    plan = Plan(
        entry_lps=entry,
        target_lps=target,
        landmarks=(CanalLandmark("right canal", canal, m.canal_radius_mm),),
        margin_mm=2.0,
    )
    got = safe_depth(plan).depth_mm
    # independent reference: the tip is the drill's nearest point to a canal below it, so the
    # stop is where the tip's distance to the centreline polyline is radius + margin
    a, b = canal[:-1], canal[1:]
    depths = np.arange(0.0, 18.0, 0.0005)
    tips = entry - depths[:, None] * [0.0, 0.0, 1.0]
    ab = b - a
    t = np.clip(
        np.einsum("dsk,sk->ds", tips[:, None] - a, ab) / np.einsum("sk,sk->s", ab, ab), 0, 1
    )
    dist = np.linalg.norm(tips[:, None] - (a + t[..., None] * ab), axis=2).min(axis=1)
    expected = depths[np.argmax(dist < m.canal_radius_mm + 2.0) - 1]
    assert got == pytest.approx(expected, abs=0.01)
    # 16 mm above a centreline point: at most 16 - 1.2 - 2, less where the canal slopes up
    assert 12.0 < got <= 16.0 - m.canal_radius_mm - 2.0 + 1e-6


def test_synthetic_ct_round_trips_through_files(mandible: RealMandible, tmp_path: Path) -> None:
    v = mandible.volume
    for path in (
        write_nifti(tmp_path / "m.nii.gz", v.hu, v.affine_lps),
        write_mha(tmp_path / "m.mha", v.hu, v.affine_lps, compress=True),
    ):
        back = load_ct(path)
        np.testing.assert_array_equal(back.hu, v.hu)
        np.testing.assert_allclose(back.affine_lps, v.affine_lps, rtol=0, atol=1e-4)


def _crest_over(m: RealMandible, point_lps: np.ndarray) -> np.ndarray:
    """The bone's top (LPS) straight above ``point_lps``: the last mask voxel going superior."""
    v = m.volume
    zs = np.arange(0.0, 60.0, 0.05)
    line = point_lps + zs[:, None] * [0.0, 0.0, 1.0]
    kji = np.rint(v.lps_to_index(line)[:, ::-1]).astype(int)
    inside = np.all((kji >= 0) & (kji < m.bone.shape), axis=1)
    bone = np.zeros(len(zs), dtype=bool)
    bone[inside] = m.bone[tuple(kji[inside].T)]
    assert bone[0], "the arch point lies in the bone"
    top = int(np.argmin(bone)) - 1  # the last bone sample of the first run
    return np.asarray(line[top])


def _mask_run_mm(m: RealMandible, start_lps: np.ndarray, direction: np.ndarray) -> float:
    """How far the bone mask runs from ``start_lps`` along ``direction`` (nearest voxel)."""
    steps = np.arange(0.0, 30.0, 0.02)
    kji = np.rint(m.volume.lps_to_index(start_lps + steps[:, None] * direction)[:, ::-1])
    kji = kji.astype(int)
    inside = np.all((kji >= 0) & (kji < m.bone.shape), axis=1)
    bone = np.zeros(len(steps), dtype=bool)
    bone[inside] = m.bone[tuple(kji[inside].T)]
    return float(steps[int(np.argmin(bone))]) if not bone.all() else math.inf


def test_bone_walls_around_an_implant_in_the_real_symphysis(mandible: RealMandible) -> None:
    """A cylindrical implant set vertically 3 mm into the crest at the arch's midline (the
    symphysis, no canal): its buccal and lingual walls, read from the CT's samples, match the
    real mask's extent along the same rays, within two voxels (each
    end: the 150 HU edge of trilinear samples against the mask's nearest-voxel boundary, half a
    voxel each, plus the resampled mask's own half voxel) wherever the surface is vertical
    (the mask's extent the same 1 mm above and below); where it slopes, the mask's voxel
    staircase is no reference for a horizontal ray."""
    from ctdrill.imaging.plan.implants import ImplantSpec
    from ctdrill.imaging.sampling.walls import MAX_WALL_MM, plan_bone_walls

    m = mandible
    mid = m.arch_lps[len(m.arch_lps) // 2]
    axis = np.array([0.0, 0.0, -1.0])
    platform = _crest_over(m, mid) + 3.0 * axis  # 3 mm into the bone: the crest is knife-edged
    spec = ImplantSpec("cylinder 4.1 x 10", 4.1, 10.0, 4.1, "flat")
    plan = Plan(
        entry_lps=platform,
        target_lps=platform + spec.length_mm * axis,
        implant=spec,
        arch_lps=m.arch_lps,
    )
    walls = plan_bone_walls(m.volume, plan)
    assert walls is not None and walls.buccal_mm is not None and walls.lingual_mm is not None
    assert walls.unknown_fraction == 0.0
    buccal = walls.buccal_lps
    assert buccal is not None and abs(buccal @ axis) < 1e-9
    sides = {"buccal": 0, "lingual": len(walls.directions_lps) // 2}
    np.testing.assert_allclose(walls.directions_lps[sides["buccal"]], buccal, atol=1e-9)
    tol = 2 * 0.75
    checked = 0
    for d, depth in enumerate(walls.depth_grid_mm):
        if not 1.0 <= depth - walls.depth_grid_mm[0] <= spec.length_mm - 1.0:
            continue  # the platform at the rounded crest and the apex face
        for a in sides.values():
            ray = walls.directions_lps[a]
            runs = [_mask_run_mm(m, platform + (depth + dz) * axis, ray) for dz in (-1, 0, 1)]
            if max(runs) - min(runs) > 1e-9:
                continue  # the surface slopes here: the mask's staircase is no reference
            expected = min(runs[1] - 2.05, MAX_WALL_MM)
            assert walls.wall_mm[d, a] == pytest.approx(expected, abs=tol), (depth, a)
            checked += 1
    assert checked >= 20, checked
    # buccal and lingual: the thinnest walls facing out of and into the arch
    side = walls.directions_lps @ buccal
    assert walls.buccal_mm == pytest.approx(np.nanmin(walls.wall_mm[:, side > 1e-9]), abs=1e-9)
    assert walls.lingual_mm == pytest.approx(np.nanmin(walls.wall_mm[:, side < -1e-9]), abs=1e-9)
