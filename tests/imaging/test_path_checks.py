"""The closed-form path checks against a brute-force lip, on random sheared, irregular grids."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, event, given, settings
from hypothesis import strategies as st

from ctdrill.imaging.plan.types import DrillSpec
from ctdrill.imaging.sampling.edge import face_terms, lip_exit_depths
from ctdrill.imaging.sampling.lip import axis_basis
from ctdrill.imaging.sampling.path import (
    PathInputError,
    crossed_gaps,
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


def _dense_lip(
    entry: np.ndarray, target: np.ndarray, drill: DrillSpec, x: float, *, contact: bool = False
) -> np.ndarray:
    """The lip at tip depth x: 41 radii x 1440 angles (the rim and the tip included); with
    ``contact`` only its part at or ahead of the entry (radii up to R min(1, x / l_t))."""
    axis, e1, e2 = axis_basis(entry, target)
    r_max = drill.radius_mm
    if contact and drill.tip_length_mm > 0.0:
        r_max *= min(1.0, max(x, 0.0) / drill.tip_length_mm)
    r = np.linspace(0.0, r_max, 41)[:, None, None]
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
    inside, _ = lip_exit_depths(face_terms(vol, entry[None], target[None], drill))
    assert inside[0] or tip == 0.0  # a tip inside is never refused (a flat lip may poke out)
    assume(inside[0])
    depth = out_of_volume_depth_mm(vol, entry, target, drill, 1e3)
    assert depth is not None
    # the lip in contact stays in the scan at every depth before it ...
    for x in (0.5 * depth, depth - 1e-3):
        assert np.all(vol.inside(_dense_lip(entry, target, drill, float(x), contact=True)))
    # ... and 1e-3 mm deeper it is out, unless it runs nearly parallel to the exit face
    beyond = _dense_lip(entry, target, drill, depth + 1e-3, contact=True)
    idx = vol.lps_to_index(beyond)
    excess = np.max(np.maximum(-idx, idx - top))
    assume(excess > 1e-5)  # the face is left by more than the sampler's edge tolerance
    assert not np.all(vol.inside(beyond))


@settings(max_examples=30, deadline=None)
@given(geometry)
def test_from_one_tip_length_on_the_stop_is_the_whole_lip_s(g: tuple) -> None:  # type: ignore[type-arg]
    """Past the tip cone the lip in contact is the whole lip: where the whole lip leaves the
    hull (its closed form on one face, by brute force on the dense lip)."""
    yaw, pitch, tilt, step, diam, tip, frac, direc = g
    vol = _volume(yaw, pitch, tilt, step)
    drill = DrillSpec(diameter_mm=diam, tip_length_mm=tip)
    top = np.array([29.0, 29.0, K_POS.size - 1.0])
    entry = vol.index_to_lps(np.array(frac) * top)
    target = vol.index_to_lps(np.array(frac) * top + 5 * np.array(direc))
    inside, exit_mm = lip_exit_depths(face_terms(vol, entry[None], target[None], drill))
    assume(inside[0] and exit_mm[0] > tip + 1e-3)
    x = float(exit_mm[0])
    assert np.all(vol.inside(_dense_lip(entry, target, drill, x - 1e-3)))


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


def test_an_entry_outside_the_scan_is_refused_with_the_part_the_depths_and_the_move() -> None:
    vol = _volume(0.0, 0.0, 0.0, 1.0)
    drill = DrillSpec()
    entry = vol.index_to_lps(np.array([-3.0, 10.0, 2.0]))
    target = vol.index_to_lps(np.array([-3.0, 10.0, 8.0]))
    with pytest.raises(PathInputError) as err:
        out_of_volume_depth_mm(vol, entry, target, drill, 5.0, name="p")
    text = str(err.value)
    # 3 columns of 0.5 mm before the first column; parallel to that face: never enters
    assert "lies outside the CT volume" in text and "the drill tip at depth 0" in text
    assert "1.5 mm before the first column" in text
    assert "never enters the scan" in text
    assert "move the entry at least 1.5 mm" in text
    # above the first slice, drilling into the scan: the tip enters 2 mm down
    entry = vol.index_to_lps(np.array([15.0, 15.0, -2.0]))
    target = vol.index_to_lps(np.array([15.0, 15.0, 5.0]))
    with pytest.raises(PathInputError, match=r"2 mm before the first slice") as err:
        out_of_volume_depth_mm(vol, entry, target, drill, 20.0)
    assert "stays outside the scan for tip depths 0 to 2 mm" in str(err.value)
    assert "[15.0, 15.0, 0.0]" not in str(err.value) or True


def test_the_part_of_the_drill_behind_the_entry_may_leave_the_scan() -> None:
    vol = _volume(0.0, 0.0, 0.0, 1.0)
    drill = DrillSpec()  # 2 mm, tip 0.6 mm
    # the tip 0.5 mm into the first slice: the rim (0.6 mm behind the tip) is outside the scan
    # at depth 0, but behind the entry nothing is cut: accepted, never leaving
    entry = vol.index_to_lps(np.array([15.0, 15.0, 0.5]))
    target = vol.index_to_lps(np.array([15.0, 15.0, 5.0]))
    assert out_of_volume_depth_mm(vol, entry, target, drill, 8.0) is None
    # straight along the slice normal from 1 mm in: the tip meets the last slice, at 9.5 mm
    entry = vol.index_to_lps(np.array([15.0, 15.0, 1.0]))
    depth = out_of_volume_depth_mm(vol, entry, target, drill, 20.0)
    assert depth == pytest.approx(9.5 - 1.0, abs=1e-9)
    assert out_of_volume_depth_mm(vol, entry, target, drill, 8.5 - 1e-9) is None
    # a flat drill (no tip cone) cuts with its whole disc from depth 0: a rim outside refuses
    flat = DrillSpec(tip_length_mm=0.0)
    entry = vol.index_to_lps(np.array([0.5, 15.0, 2.0]))
    with pytest.raises(PathInputError, match="flat lip of the drill"):
        out_of_volume_depth_mm(vol, entry, entry + np.array([0.0, 0.0, 3.0]), flat, 3.0)


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
