"""The closed-form path checks against a brute-force lip, on random sheared, irregular grids."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, event, given, settings
from hypothesis import strategies as st

from ctdrill.imaging.plan.types import DrillSpec
from ctdrill.imaging.sampling.lip import axis_basis
from ctdrill.imaging.sampling.path import (
    PathInputError,
    crossed_gaps,
    lip_inside_depths_mm,
    out_of_volume_depth_mm,
)
from ctdrill.imaging.volume import CTVolume, SeriesInfo
from tests.imaging.factory import affine, rotation

#: Slice positions (in nominal steps) with a gap of 3 steps between slices 3 and 4.
K_POS = np.array([0.0, 1.0, 2.0, 3.0, 6.0, 7.0, 7.5, 8.5, 9.5])


def _volume(yaw: float, pitch: float, tilt: float, step: float) -> CTVolume:
    aff = affine((0.5, 0.6, step), rot=rotation(yaw, pitch, 10.0), tilt_deg=tilt)
    normal = np.cross(aff[:3, 0], aff[:3, 1])
    normal /= np.linalg.norm(normal)
    p0 = float(aff[:3, 3] @ normal)
    return CTVolume(
        hu=np.zeros((K_POS.size, 30, 30), np.int16),
        affine_lps=aff,
        valid=None,
        info=SeriesInfo(series_uid="1"),
        slice_positions_mm=p0 + step * K_POS,
    )


def _dense_lip(entry: np.ndarray, target: np.ndarray, drill: DrillSpec, x: float) -> np.ndarray:
    """The lip at tip depth x: 41 radii x 1440 angles (the rim and the tip included)."""
    axis, e1, e2 = axis_basis(entry, target)
    r = np.linspace(0.0, drill.radius_mm, 41)[:, None, None]
    th = np.linspace(0.0, 2 * np.pi, 1440, endpoint=False)[None, :, None]
    xi = x - drill.tip_length_mm * r / drill.radius_mm
    pts = entry + xi * axis + r * (np.cos(th) * e1 + np.sin(th) * e2)
    return pts.reshape(-1, 3)


def _true_k(vol: CTVolume, pts: np.ndarray) -> np.ndarray:
    return vol.lps_to_index(pts)[:, 2]


geometry = st.tuples(
    st.floats(-40, 40),  # yaw
    st.floats(-30, 30),  # pitch
    st.floats(-20, 20),  # gantry tilt
    st.floats(0.3, 1.2),  # nominal step
    st.floats(0.8, 2.5),  # drill diameter
    st.floats(0.0, 1.0),  # tip length
    st.tuples(st.floats(0.3, 0.7), st.floats(0.3, 0.7), st.floats(0.1, 0.3)),  # entry (frac)
    st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(0.2, 1)),  # direction (index)
)


@settings(max_examples=40, deadline=None)
@given(geometry)
def test_out_of_volume_depth_is_where_the_brute_force_lip_leaves(g: tuple) -> None:  # type: ignore[type-arg]
    yaw, pitch, tilt, step, diam, tip, frac, direc = g
    vol = _volume(yaw, pitch, tilt, step)
    drill = DrillSpec(diameter_mm=diam, tip_length_mm=tip)
    top = np.array([29.0, 29.0, K_POS.size - 1.0])
    entry = vol.index_to_lps(np.array(frac) * top)
    target = vol.index_to_lps(np.array(frac) * top + 5 * np.array(direc))
    lo, hi = lip_inside_depths_mm(vol, entry, target, drill)
    assume(lo < 0.0 < hi)  # the lip fits at the entry
    depth = out_of_volume_depth_mm(vol, entry, target, drill, 1e3)
    assert depth is not None and depth == pytest.approx(hi)
    assert np.all(vol.inside(_dense_lip(entry, target, drill, depth - 1e-3)))
    # 1e-3 mm deeper the lip is out, unless it runs nearly parallel to the exit face
    beyond = _dense_lip(entry, target, drill, depth + 1e-3)
    idx = vol.lps_to_index(beyond)
    excess = np.max(np.maximum(-idx, idx - top))
    assume(excess > 1e-5)  # the face is left by more than the sampler's edge tolerance
    assert not np.all(vol.inside(beyond))


@settings(max_examples=40, deadline=None)
@given(geometry, st.floats(0.5, 12.0))
def test_crossed_gap_depths_match_the_brute_force_lip(g: tuple, planned: float) -> None:  # type: ignore[type-arg]
    yaw, pitch, tilt, step, diam, tip, frac, direc = g
    vol = _volume(yaw, pitch, tilt, step)
    drill = DrillSpec(diameter_mm=diam, tip_length_mm=tip)
    top = np.array([29.0, 29.0, K_POS.size - 1.0])
    entry = vol.index_to_lps(np.array(frac) * top)
    target = vol.index_to_lps(np.array(frac) * top + 5 * np.array(direc))
    gaps = crossed_gaps(vol, entry, target, drill, planned)
    event(f"gaps crossed: {len(gaps)}")
    # the only gap is between slices 3 and 4 (3 nominal steps); slice 5->6 is 0.5 (not a gap)
    assert all(
        (g.lower_mm, g.upper_mm) == (vol.slice_positions_mm[3], vol.slice_positions_mm[4])
        for g in gaps
    )
    for x in np.linspace(0.0, planned, 23):
        k = _true_k(vol, _dense_lip(entry, target, drill, float(x)))
        inside_gap = bool(np.any((k > 3.0 + 1e-9) & (k < 4.0 - 1e-9)))
        if gaps:
            within = gaps[0].depth_from_mm + 1e-6 < x < gaps[0].depth_to_mm - 1e-6
            outside = x < gaps[0].depth_from_mm - 1e-3 or x > gaps[0].depth_to_mm + 1e-3
            if within:
                assert inside_gap
            if outside:
                assert not inside_gap
        else:
            assert not inside_gap


def test_an_entry_outside_the_scan_is_refused() -> None:
    vol = _volume(0.0, 0.0, 0.0, 1.0)
    drill = DrillSpec()
    entry = vol.index_to_lps(np.array([-3.0, 10.0, 2.0]))
    target = vol.index_to_lps(np.array([-3.0, 10.0, 8.0]))
    with pytest.raises(PathInputError, match="lies outside the CT volume"):
        out_of_volume_depth_mm(vol, entry, target, drill, 5.0, name="p")
    # the tip 0.5 mm into the first slice: the lip's rim (0.6 mm behind the tip) is not
    entry = vol.index_to_lps(np.array([15.0, 15.0, 0.5]))
    target = vol.index_to_lps(np.array([15.0, 15.0, 5.0]))
    with pytest.raises(PathInputError, match="lies outside the CT volume"):
        out_of_volume_depth_mm(vol, entry, target, drill, 20.0)
    # straight along the slice normal from 1 mm in: the tip meets the last slice, at 9.5 mm
    entry = vol.index_to_lps(np.array([15.0, 15.0, 1.0]))
    depth = out_of_volume_depth_mm(vol, entry, target, drill, 20.0)
    assert depth == pytest.approx(9.5 - 1.0, abs=1e-9)
    assert out_of_volume_depth_mm(vol, entry, target, drill, 8.5 - 1e-9) is None


def test_a_mask_without_its_own_grid_needs_a_regular_ct() -> None:
    from ctdrill.imaging.plan.landmarks import MaskLandmark
    from ctdrill.imaging.sampling.path import require_grid_for_masks

    irregular = _volume(0.0, 0.0, 0.0, 1.0)
    mask = MaskLandmark("canal", np.ones((K_POS.size, 30, 30), dtype=bool))
    with pytest.raises(PathInputError, match="mask landmark 'canal' has no affine_lps"):
        require_grid_for_masks(irregular, (mask,), name="p")
    regular = CTVolume(
        hu=irregular.hu, affine_lps=irregular.affine_lps, valid=None, info=irregular.info
    )
    require_grid_for_masks(regular, (mask,), name="p")  # the CT's grid is true: fine
