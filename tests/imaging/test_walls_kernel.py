"""The compiled envelope rays and suggest's compiled shells against their NumPy paths.

Both kernels read the same trilinear samples as :meth:`CTVolume.sample` (the same points, the
same weights) and apply the same rules, so the flags agree exactly and the shell HU to float
rounding of the index arithmetic (1e-9 HU); a wall agrees bit for bit (each ray bisected
alike on the same samples: ``CTVolume.sample`` builds its index coordinates in the kernels'
order). The lip rings' kernel gives the sampler's bits too. The volumes: the demo
(int16), the demo as float32 with a tooth block (CT numbers >= 2000 HU and their trilinear
edge), and an irregular stack (slices dropped: true slice positions remapped).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ctdrill import jit
from ctdrill.app.search.shell import body_profile, sample_shells
from ctdrill.app.search.shell_kernel import SHELL_KERNEL
from ctdrill.imaging.dicom.series import load_series
from ctdrill.imaging.plan.implants import load_implant_library
from ctdrill.imaging.plan.load import load_plan
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.sampling.envelope import envelope_walls
from ctdrill.imaging.sampling.envelope_kernel import ENVELOPE_KERNEL
from ctdrill.imaging.sampling.lip import axis_basis
from ctdrill.imaging.sampling.lip_batch import LIP_KERNEL, sample_lips
from ctdrill.imaging.sampling.walls import plan_bone_walls, ray_step_mm
from ctdrill.imaging.volume import CTVolume
from tests.conftest import ASSETS

KERNELS = (ENVELOPE_KERNEL, SHELL_KERNEL, LIP_KERNEL)


@pytest.fixture(scope="module", autouse=True)
def kernels() -> None:
    """The kernels as `make warmup` leaves them (compiled here when the cache is missing)."""
    jit.warm_up(KERNELS)
    assert all(k.ready() for k in KERNELS)


@pytest.fixture(scope="module")
def demo() -> tuple[CTVolume, Plan]:
    return load_series(ASSETS / "demo" / "ct"), load_plan(ASSETS / "demo" / "plan.json")


def _with_tooth(volume: CTVolume, plan: Plan) -> CTVolume:
    """The demo as float32 with a 2500 HU block beside the planned entry."""
    hu = np.array(volume.hu, dtype=np.float32)
    k, j, i = np.rint(volume.lps_to_index(plan.entry_lps)[::-1]).astype(int)
    hu[k - 6 : k + 2, j - 4 : j + 4, i + 3 : i + 9] = 2500.0
    return CTVolume(hu, volume.affine_lps, None, volume.info)


def _irregular(volume: CTVolume) -> CTVolume:
    keep = np.ones(volume.hu.shape[0], dtype=bool)
    keep[[20, 41, 42]] = False
    out = CTVolume(
        volume.hu[keep],
        volume.affine_lps,
        None,
        volume.info,
        slice_positions_mm=volume.slice_positions_mm[keep],
    )
    assert out._remap_k
    return out


def _volumes(volume: CTVolume, plan: Plan) -> dict[str, CTVolume]:
    return {
        "demo": volume,
        "float32 with a tooth": _with_tooth(volume, plan),
        "irregular": _irregular(volume),
    }


def test_envelope_rays_match_numpy(demo: tuple[CTVolume, Plan]) -> None:
    volume, plan = demo
    rng = np.random.default_rng(7)
    origins = plan.entry_lps + rng.normal(0.0, 7.0, (3000, 3))
    origins[:50] += 40.0  # outside the CT: unknown
    dirs = rng.normal(size=(3000, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    for name, vol in _volumes(volume, plan).items():
        step = ray_step_mm(vol)
        got = envelope_walls(vol, origins, dirs, step=step)
        with jit.switched_off([ENVELOPE_KERNEL]):
            want = envelope_walls(vol, origins, dirs, step=step)
        np.testing.assert_array_equal(got[1], want[1], err_msg=f"{name}: unknown")
        np.testing.assert_array_equal(got[2], want[2], err_msg=f"{name}: open")
        # bit for bit: the NumPy path bisects each ray as the kernel does
        np.testing.assert_array_equal(got[0], want[0], err_msg=name)
        # the cases are all there: walls inside the jaw, outside (0), capped, unknown, open
        assert (want[0] > 0).any() and (want[0] == 0).any() and want[1].any() and want[2].any()


def test_plan_walls_match_numpy(demo: tuple[CTVolume, Plan]) -> None:
    volume, plan = demo
    spec = next(s for s in load_implant_library() if s.name == "tapered 4.1 x 8")
    plans = [plan, replace(plan, implant=spec, target_lps=plan.entry_lps - [0.0, 0.0, 10.5])]
    for name, vol in _volumes(volume, plan).items():
        for p in plans:
            got = plan_bone_walls(vol, p)
            with jit.switched_off([ENVELOPE_KERNEL]):
                want = plan_bone_walls(vol, p)
            assert got is not None and want is not None
            np.testing.assert_array_equal(got.wall_mm, want.wall_mm, err_msg=name)
            assert (got.perforation is None) == (want.perforation is None), name
            assert got.unknown_fraction == want.unknown_fraction


def test_shells_match_numpy(demo: tuple[CTVolume, Plan]) -> None:
    volume, plan = demo
    rng = np.random.default_rng(3)
    n = 300
    entries = plan.entry_lps + rng.normal(0.0, 3.0, (n, 3))
    entries[:10, 2] += 30.0  # partly outside the CT: air
    dirs = plan.direction + rng.normal(0.0, 0.3, (n, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    body = body_profile(plan.for_drill(len(plan.drills) - 1))
    for name, vol in _volumes(volume, plan).items():
        got = sample_shells(vol, body, entries, dirs, min_wall_mm=plan.min_wall_mm)
        with jit.switched_off([SHELL_KERNEL]):
            want = sample_shells(vol, body, entries, dirs, min_wall_mm=plan.min_wall_mm)
        np.testing.assert_allclose(got.hu, want.hu, rtol=0, atol=1e-9, err_msg=name)
        np.testing.assert_array_equal(got.likely_perforation, want.likely_perforation, name)
        np.testing.assert_array_equal(got.likely_thin_wall, want.likely_thin_wall, name)
        assert want.likely_perforation.any() and (~want.likely_thin_wall).any(), name


def test_lip_rings_match_the_sampler_bit_for_bit(demo: tuple[CTVolume, Plan]) -> None:
    """The lip kernel's float32 ring samples and outside counts are the per-trajectory
    sampler's (its NumPy path), bit for bit: 60 axes partly outside the CT, on the three
    volumes."""
    volume, plan = demo
    rng = np.random.default_rng(11)
    n = 60
    entries = plan.entry_lps + rng.normal(0.0, 6.0, (n, 3))
    entries[:5] += 30.0  # partly outside the CT
    axes = plan.direction + rng.normal(0.0, 0.4, (n, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    depth_len = rng.uniform(2.0, 14.0, n)
    targets = entries + depth_len[:, None] * axes
    d_max = 60
    depth = np.tile(np.arange(d_max) * 0.2, (n, 1))
    n_depths = np.minimum(d_max, np.floor(depth_len / 0.2).astype(np.int64) + 1)
    bases = np.stack([axis_basis(e, t) for e, t in zip(entries, targets, strict=True)])
    for name, vol in _volumes(volume, plan).items():
        got = sample_lips(
            vol, entries, targets, bases, depth, n_depths, plan.drill, n_rings=4, n_angles=24
        )
        with jit.switched_off([LIP_KERNEL]):
            want = sample_lips(
                vol, entries, targets, bases, depth, n_depths, plan.drill, n_rings=4, n_angles=24
            )
        for i in range(n):
            m = int(n_depths[i])
            assert np.array_equal(got[0][i, :m].view(np.uint32), want[0][i, :m].view(np.uint32))
            assert np.array_equal(got[1][i, :m], want[1][i, :m]), name
