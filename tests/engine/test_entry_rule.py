"""The entry rule on a tilted 0.3 mm stack: an entry inside the scan is never refused because
the drill behind the entry leaves it; an entry outside is refused with the part, the depths
and the distance (closed forms on the slice planes z = 0.3 k)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ctdrill.engine.batch import evaluate_batch
from ctdrill.engine.path import PathInputError, plan_path
from ctdrill.imaging.plan.types import DrillSpec, Plan
from ctdrill.imaging.sampling.lip import axis_basis
from ctdrill.imaging.volume import CTVolume, SeriesInfo
from ctdrill.model.calibration import load_calibration
from tests.imaging.factory import affine

STEP = 0.3
#: Axis tilt from the slice normal, degrees: with the 2 mm drill's 0.6 mm tip, the shoulder
#: (the rim behind the entry at depth 0) lies 0.6 cos + 1.0 sin = 0.790 mm below the tip.
TILT_DEG = 11.7
DRILL = DrillSpec(diameter_mm=2.0, tip_length_mm=0.6)


def _tilted_stack() -> CTVolume:
    """40 x 40 x 30 voxels of 0.3 mm, gantry tilt 15 degrees, the first slice plane at z = 0;
    bone (1000 HU) below z = 2 mm, soft tissue (40 HU) above."""
    aff = affine((STEP, STEP, STEP), origin_lps=(0.0, 0.0, 0.0), tilt_deg=15.0)
    z = STEP * np.arange(30)
    hu = np.where(z >= 2.0, 1000, 40).astype(np.int16)[:, None, None] * np.ones((1, 40, 40))
    return CTVolume(
        hu=hu.astype(np.int16), affine_lps=aff, valid=None, info=SeriesInfo(series_uid="7.7")
    )


def _plan(entry_z_mm: float, depth_mm: float = 5.0) -> Plan:
    t = math.radians(TILT_DEG)
    entry = np.array([6.0, 7.5, entry_z_mm])
    axis = np.array([math.sin(t), 0.0, math.cos(t)])
    return Plan(
        entry_lps=entry,
        target_lps=entry + depth_mm * axis,
        drill=DRILL,
        calibration="bone-illustrative",
        name="tilted",
    )


def test_an_entry_inside_is_never_refused_for_the_shoulder_behind_it() -> None:
    volume, plan = _tilted_stack(), _plan(0.69)
    # the case: the tip 0.69 mm inside the first slice, the whole lip's shoulder ~0.1 mm out
    axis, e1, e2 = axis_basis(plan.entry_lps, plan.target_lps)
    theta = np.linspace(0.0, 2.0 * np.pi, 3600, endpoint=False)[:, None]
    rim = plan.entry_lps - 0.6 * axis + 1.0 * (np.cos(theta) * e1 + np.sin(theta) * e2)
    t = math.radians(TILT_DEG)
    assert float(rim[:, 2].min()) == pytest.approx(0.69 - 0.6 * math.cos(t) - math.sin(t))
    assert float(rim[:, 2].min()) == pytest.approx(-0.1, abs=1e-3)  # the old rule refused this
    assert not np.all(volume.inside(rim))
    result = plan_path(volume, plan, load_calibration("bone-illustrative"))
    assert result.stop_reason == "planned_depth" and result.out_of_volume_depth_mm is None
    assert "out_of_volume" not in {w.code for w in result.warnings}
    # the force starts where the tip (the lip's highest point) first reads HU above the gate's
    # low end (125 HU: trilinear between 40 HU at z = 1.8 and 1000 HU at z = 2.1)
    z_cut = 1.8 + STEP * (125.0 - 40.0) / 960.0
    x_cut = (z_cut - 0.69) / math.cos(math.radians(TILT_DEG))
    s0 = result.profile.s0_n
    assert np.all(s0[result.depth_mm < x_cut - 0.01] == 0.0)
    assert np.all(s0[result.depth_mm > x_cut + 0.1] > 0.0)
    batch = evaluate_batch(
        volume,
        plan,
        plan.entry_lps[None],
        plan.target_lps[None],
        load_calibration("bone-illustrative"),
    )
    assert batch.refusal == (None,)
    np.testing.assert_array_equal(batch.s0_n[0, : s0.size], s0)


def test_an_entry_outside_names_the_part_the_depths_and_the_move() -> None:
    volume, plan = _tilted_stack(), _plan(-0.5)
    with pytest.raises(PathInputError) as err:
        plan_path(volume, plan, load_calibration("bone-illustrative"))
    text = str(err.value)
    enters = 0.5 / math.cos(math.radians(TILT_DEG))  # the tip reaches z = 0 there
    assert "plan 'tilted': the entry point [6.0, 7.5, -0.5] (LPS mm) lies outside" in text
    assert "the drill tip at depth 0 is 0.5 mm before the first slice of the scan" in text
    assert f"stays outside the scan for tip depths 0 to {enters:.3f} mm" in text
    assert "move the entry at least 0.5 mm into the scanned field" in text
    assert "[6.0, 7.5, 0.0]" in text  # the nearest point inside
    assert "only the lip ahead of the entry must lie in the scan" in text


@pytest.mark.parametrize(
    ("diameter_mm", "entry_xy_mm", "tilt_deg"),
    [(13.0, (6.0, 6.0), 0.0), (11.5, (5.7, 6.2), 20.0), (12.2, (9.0, 3.0), 8.0)],
)
def test_a_drill_whose_whole_lip_fits_nowhere_is_refused(
    diameter_mm: float, entry_xy_mm: tuple[float, float], tilt_deg: float
) -> None:
    # The stack is 11.7 x 11.7 mm across (40 columns of 0.3 mm): a drill wider than that
    # around its axis has no depth with its whole lip inside; its tip is (the entry lies in
    # the scan), so the entry rule alone would let it drill a few tenths of a millimetre.
    volume = _tilted_stack()
    t = math.radians(tilt_deg)
    entry = np.array([*entry_xy_mm, 2.5])
    drill = DrillSpec(diameter_mm=diameter_mm, tip_length_mm=0.6)
    plan = Plan(
        entry_lps=entry,
        target_lps=entry + 5.0 * np.array([math.sin(t), 0.0, math.cos(t)]),
        drill=drill,
        calibration="bone-illustrative",
        name="wide",
    )
    cal = load_calibration("bone-illustrative")
    with pytest.raises(PathInputError, match=r"wider than the scan around its axis"):
        plan_path(volume, plan, cal)
    batch = evaluate_batch(volume, plan, plan.entry_lps[None], plan.target_lps[None], cal)
    assert batch.refusal[0] is not None and "wider than the scan" in str(batch.refusal[0])
    # a drill that fits around the same axis is not refused
    narrow = Plan(
        entry_lps=plan.entry_lps,
        target_lps=plan.target_lps,
        drill=DrillSpec(diameter_mm=2.0, tip_length_mm=0.6),
        calibration="bone-illustrative",
        name="narrow",
    )
    assert plan_path(volume, narrow, cal).stop_depth_mm > 0.0
