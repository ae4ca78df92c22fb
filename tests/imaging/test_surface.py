"""The first crossing into bone along lines: closed forms on a slab, and every "no surface"."""

from __future__ import annotations

import numpy as np
import pytest

from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.misch import BONE_HU
from ctdrill.imaging.sampling.surface import SURFACE_TOL_MM, first_bone_crossing_mm
from ctdrill.imaging.volume import CTVolume, SeriesInfo

STEP = 0.5  # voxel, mm
SOFT, BONE = 40.0, 1000.0


def _slab(valid: np.ndarray | None = None) -> CTVolume:
    """x, y in [-5, 5], z centres from -9.75 to 9.75: soft tissue above z = 0, bone below."""
    zs = np.arange(-9.75, 10.0, STEP)
    hu = np.where(zs < 0.0, BONE, SOFT)[:, None, None] * np.ones((1, 21, 21))
    aff = np.diag([STEP, STEP, STEP, 1.0])
    aff[:3, 3] = [-5.0, -5.0, zs[0]]
    return CTVolume(
        hu=hu.astype(np.float32), affine_lps=aff, valid=valid, info=SeriesInfo(series_uid="1")
    )


def _crossing_z() -> float:
    """HU is linear between the centres z = 0.25 (soft) and z = -0.25 (bone)."""
    return 0.25 - (BONE_HU - SOFT) / (BONE - SOFT) * STEP


def test_vertical_and_oblique_lines_cross_where_the_ramp_meets_the_threshold() -> None:
    vol = _slab()
    down = np.array([0.0, 0.0, -1.0])
    tilt = np.array([np.sin(0.3), 0.0, -np.cos(0.3)])
    origins = np.array([[0.0, 0.0, 3.0], [1.0, -2.0, 3.0]])
    t = first_bone_crossing_mm(vol, origins, np.stack([down, tilt]), start_mm=-2.0, stop_mm=8.0)
    z = origins[:, 2] + t * np.array([down[2], tilt[2]])
    assert z == pytest.approx([_crossing_z()] * 2, abs=2 * SURFACE_TOL_MM)


def test_no_surface_is_nan_never_a_guess() -> None:
    vol = _slab()
    down = np.array([[0.0, 0.0, -1.0]])
    # starts inside bone; never reaches bone; enters the grid from outside straight into bone
    # (the volume's side cut through the bone: no measured sample above the threshold first)
    cases = [
        ([0.0, 0.0, -3.0], down[0]),
        ([0.0, 0.0, 8.0], -down[0]),
        ([-8.0, 0.0, -3.0], np.array([1.0, 0.0, 0.0])),
    ]
    t = first_bone_crossing_mm(
        vol,
        np.array([c[0] for c in cases]),
        np.array([c[1] for c in cases]),
        start_mm=0.0,
        stop_mm=6.0,
    )
    assert np.all(np.isnan(t))


def test_padding_is_unknown_not_air() -> None:
    valid = np.ones((40, 21, 21), dtype=bool)
    valid[19:21] = False  # the two slices around the surface are padding
    t = first_bone_crossing_mm(
        _slab(valid),
        np.array([[0.0, 0.0, 3.0]]),
        np.array([[0.0, 0.0, -1.0]]),
        start_mm=0.0,
        stop_mm=6.0,
    )
    assert np.isnan(t[0])


def test_bad_arguments_are_refused() -> None:
    vol = _slab()
    with pytest.raises(ImagingInputError, match="start_mm < stop_mm"):
        first_bone_crossing_mm(vol, np.zeros((1, 3)), np.ones((1, 3)), start_mm=1.0, stop_mm=1.0)
    with pytest.raises(ImagingInputError, match="directions"):
        first_bone_crossing_mm(vol, np.zeros((2, 3)), np.ones((1, 3)), start_mm=0.0, stop_mm=1.0)


def test_long_searches_go_in_chunks_with_the_same_answers(monkeypatch: pytest.MonkeyPatch) -> None:
    import ctdrill.imaging.sampling.surface as mod

    vol = _slab()
    rng = np.random.default_rng(5)
    origins = np.column_stack([rng.uniform(-3, 3, 50), rng.uniform(-3, 3, 50), np.full(50, 3.0)])
    dirs = np.tile([0.0, 0.0, -1.0], (50, 1))
    whole = first_bone_crossing_mm(vol, origins, dirs, start_mm=0.0, stop_mm=6.0)
    monkeypatch.setattr(mod, "_CHUNK_SAMPLES", 200)  # 3 lines of 61 samples per chunk
    chunked = first_bone_crossing_mm(vol, origins, dirs, start_mm=0.0, stop_mm=6.0)
    assert np.array_equal(whole, chunked) and np.all(np.isfinite(whole))
