"""The bone walls' rays stepping over uniform blocks (:mod:`ctdrill.imaging.sampling.hu_blocks`)
give the full march's answers.

Random small CTs (int16 and float32, axis-aligned and rotated grids) built from blocks of one
CT number, thin walls one voxel thick, single voxels, and values exactly at and one HU either
side of each threshold (air, bone, tooth); rays from inside and outside the CT, along the grid's
axes through voxel centres and faces (a ray grazing a crossing) and in random directions. The
skipping kernel must give bit for bit the walls, unknown and open flags of the compiled full
march (every sample read: its decisions are the same, only the samples it does not need are
not read), and the NumPy reference's within the bisection's tolerance.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ctdrill import jit
from ctdrill.imaging.misch import BONE_HU
from ctdrill.imaging.sampling.envelope import (
    AIR_HU,
    BISECT_TOL_MM,
    ENVELOPE_GAP_MM,
    ENVELOPE_REACH_MM,
    MAX_ENVELOPE_MM,
    envelope_walls,
)
from ctdrill.imaging.sampling.envelope_kernel import ENVELOPE_KERNEL
from ctdrill.imaging.sampling.envelope_march import envelope_rays
from ctdrill.imaging.sampling.hu_blocks import (
    BLOCK,
    BONE,
    MIXED,
    SOFT,
    UNKNOWN,
    block_classes,
    block_code,
)
from ctdrill.imaging.teeth import TOOTH_HU, edge_steps
from ctdrill.imaging.volume import CTVolume
from tests.imaging.factory import affine, rotation, volume

#: CT numbers at, and one HU either side of, every threshold of the rule, and between them ...
PALETTE = (-1000, -401, -400, -399, 0, 60, 149, 150, 151, 1050, 1700, 1999, 2000, 2001, 2600)
#: ... and off them (with the rays off voxel faces: no sample lies exactly on a threshold).
GENERIC = (-1000, -401, -399, 0, 60, 149, 151, 1050, 1700, 1999, 2001, 2600)


@pytest.fixture(scope="module", autouse=True)
def kernel() -> None:
    """The kernel as `make warmup` leaves it (compiled here when the cache is missing)."""
    jit.warm_up([ENVELOPE_KERNEL])


@st.composite
def ct_and_rays(draw: st.DrawFn, *, exact: bool) -> tuple[CTVolume, np.ndarray, np.ndarray]:
    """A small CT and rays through it; ``exact``: CT numbers exactly at the thresholds and
    rays through voxel centres and faces among them."""
    palette = PALETTE if exact else GENERIC
    shape = tuple(draw(st.integers(5, 13)) for _ in range(3))
    # blocks of one value (some larger than a skipping block, some smaller)
    size = draw(st.integers(2, 6))
    coarse = draw(
        st.lists(st.sampled_from(palette), min_size=27, max_size=27).map(
            lambda v: np.array(v).reshape(3, 3, 3)
        )
    )
    hu = np.kron(coarse, np.ones((size, size, size)))
    hu = np.pad(hu, [(0, max(0, n - m)) for n, m in zip(shape, hu.shape, strict=True)], "edge")
    hu = np.ascontiguousarray(hu[: shape[0], : shape[1], : shape[2]])
    for _ in range(draw(st.integers(0, 3))):  # thin walls: one voxel thick planes
        axis = draw(st.integers(0, 2))
        at = draw(st.integers(0, shape[axis] - 1))
        idx: list[slice | int] = [slice(None)] * 3
        idx[axis] = at
        hu[tuple(idx)] = draw(st.sampled_from(palette))
    for _ in range(draw(st.integers(0, 6))):  # single voxels
        k, j, i = (draw(st.integers(0, n - 1)) for n in shape)
        hu[k, j, i] = draw(st.sampled_from(palette))
    dtype = draw(st.sampled_from([np.int16, np.float32]))
    spacing = draw(st.sampled_from([(0.5, 0.5, 0.5), (0.4, 0.4, 0.6), (0.5, 0.3, 0.4)]))
    rot = rotation(*draw(st.sampled_from([(0.0, 0.0, 0.0), (30.0, 10.0, 0.0), (90.0, 0.0, 0.0)])))
    vol = volume(hu.astype(dtype), affine(spacing, rot=rot, origin_lps=(0.0, 0.0, 0.0)))
    n = draw(st.integers(1, 24))
    # origins in index coordinates: voxel centres and faces (grazing) or anywhere, some outside
    grid = st.sampled_from([0.0, 0.5, 1.0, 2.0, 2.5, 4.0, 5.0])
    anywhere = st.floats(-1.5, 14.0, allow_nan=False).map(lambda x: x + 1e-3 * math.pi)
    coord = st.one_of(grid, anywhere) if exact else anywhere
    origins_ijk = np.array([[draw(coord) for _ in range(3)] for _ in range(n)], dtype=np.float64)
    axes = np.vstack([np.eye(3), -np.eye(3)])
    dirs_ijk = []
    for _ in range(n):
        if exact and draw(st.booleans()):
            dirs_ijk.append(axes[draw(st.integers(0, 5))])
        else:
            v = np.array([draw(st.floats(-1.0, 1.0)) for _ in range(3)])
            dirs_ijk.append(v if np.linalg.norm(v) > 1e-3 else np.array([1.0, 0.0, 0.0]))
    origins = origins_ijk @ vol.affine_lps[:3, :3].T + vol.affine_lps[:3, 3]
    dirs = np.array(dirs_ijk) @ vol.affine_lps[:3, :3].T
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    return vol, np.ascontiguousarray(origins), np.ascontiguousarray(dirs)


def _rays(vol: CTVolume, o: np.ndarray, v: np.ndarray, *, skip: bool) -> tuple[np.ndarray, ...]:
    step = 0.5 * min(vol.spacing_mm)
    return envelope_rays(
        vol,
        o,
        v,
        step=step,
        n_steps=math.ceil((MAX_ENVELOPE_MM + ENVELOPE_GAP_MM) / step) + 1,
        gap_steps=math.ceil(ENVELOPE_GAP_MM / step - 1e-9),
        tooth_edge=edge_steps(vol, step),
        max_wall_mm=MAX_ENVELOPE_MM,
        reach_mm=ENVELOPE_REACH_MM,
        air_hu=AIR_HU,
        bisect_tol_mm=BISECT_TOL_MM,
        skip_blocks=skip,
    )


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(ct_and_rays(exact=True))
def test_skipping_equals_full_march(case: tuple[CTVolume, np.ndarray, np.ndarray]) -> None:
    vol, o, v = case
    full = _rays(vol, o, v, skip=False)
    for _ in range(2):  # blocks classed on the way, then read from the volume's cache
        got = _rays(vol, o, v, skip=True)
        for a, b in zip(got, full, strict=True):
            np.testing.assert_array_equal(a, b)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.booleans().flatmap(lambda exact: ct_and_rays(exact=exact)))
def test_skipping_equals_numpy_reference(case: tuple[CTVolume, np.ndarray, np.ndarray]) -> None:
    """Against the NumPy path (the reference), bit for bit, also with CT numbers exactly at
    the thresholds and rays along voxel faces: both read ``CTVolume.sample``'s bits (the same
    index arithmetic, map_coordinates' weights), bisect each ray alike, and decide alike (a
    sample an ulp either side of -400 HU had made a ray unknown in one and not the other)."""
    vol, o, v = case
    got = _rays(vol, o, v, skip=True)
    with jit.switched_off([ENVELOPE_KERNEL]):
        ref = envelope_walls(vol, o, v, step=0.5 * min(vol.spacing_mm))
    np.testing.assert_array_equal(got[1], ref[1])
    np.testing.assert_array_equal(got[2], ref[2])
    np.testing.assert_array_equal(got[0], ref[0])  # each ray bisected as the kernel does


@pytest.mark.parametrize(
    ("value", "plane", "want"),
    [
        (1050, None, BONE),
        (60, None, SOFT),
        (-1000, None, MIXED),  # air ends a ray at once: never stepped over
        (int(BONE_HU), None, MIXED),  # exactly at the threshold
        (int(BONE_HU) + 1, None, BONE),
        (int(BONE_HU) - 1, None, SOFT),
        (int(TOOTH_HU) - 1, None, BONE),
        (int(TOOTH_HU), None, MIXED),
        (int(AIR_HU), None, MIXED),
        (1050, 60, MIXED),  # a soft plane on the blocks' shared corners
    ],
)
def test_blocks_are_classed_conservatively(value: int, plane: int | None, want: int) -> None:
    """A block is uniform only when every corner of its cells (one voxel past it: the next
    block's first) lies strictly inside one class."""
    hu = np.full((2 * BLOCK + 1,) * 3, value, dtype=np.int16)
    if plane is not None:
        hu[:, :, BLOCK] = plane
    vol = volume(hu, affine((0.5, 0.5, 0.5)))
    blocks = block_classes(vol, AIR_HU, BONE_HU, TOOTH_HU)
    assert blocks.shape == (2, 2, 2) and (blocks == UNKNOWN).all()
    for k, j, i in np.ndindex(blocks.shape):
        code = block_code(np.asarray(vol.hu), blocks, k, j, i, AIR_HU, BONE_HU, TOOTH_HU)
        assert code == want == blocks[k, j, i]
    assert block_classes(vol, AIR_HU, BONE_HU, TOOTH_HU) is blocks  # kept with the volume


def test_demo_walls_step_over_blocks() -> None:
    """On the demo the rays of an implant step over bone and soft blocks, with the full
    march's answers."""
    from ctdrill.imaging.dicom.series import load_series
    from ctdrill.imaging.plan.load import load_plan
    from tests.conftest import ASSETS

    vol = load_series(ASSETS / "demo" / "ct")
    plan = load_plan(ASSETS / "demo" / "plan.json")
    rng = np.random.default_rng(5)
    o = plan.target_lps + rng.normal(0.0, 3.0, (400, 3))
    v = rng.normal(size=(400, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    got, full = _rays(vol, o, v, skip=True), _rays(vol, o, v, skip=False)
    for a, b in zip(got, full, strict=True):
        np.testing.assert_array_equal(a, b)
    codes = block_classes(vol, AIR_HU, BONE_HU, TOOTH_HU)
    assert (codes == BONE).sum() > 50 and (codes == SOFT).sum() > 10
