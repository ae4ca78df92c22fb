"""The implant and the whole osteotomy through the engine, on closed-form phantoms.

A bone slab whose CT numbers are linear in the distance to its nearest face
(``HU = 150 + G * distance inside``): trilinear interpolation reproduces a linear function
exactly, so the 150 HU edge the walls and the crest follow is the geometric face, and every
number below has a closed form (up to the walls' bisection tolerance and the depth grids).
Each case runs the engine's own path (``plan_path``, ``plan_sequence``) and its summary, as
``ctdrill export`` writes it.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from ctdrill.engine.implant import implant_outcome
from ctdrill.engine.implant_facts import implant_facts
from ctdrill.engine.path import plan_path
from ctdrill.engine.sequence import plan_sequence
from ctdrill.engine.settings import DEFAULTS
from ctdrill.engine.summarize import CaseContext, job_summary, sequence_summary
from ctdrill.imaging.misch import BONE_HU
from ctdrill.imaging.plan.drill_spec import DrillSpec
from ctdrill.imaging.plan.implants import ImplantSpec
from ctdrill.imaging.plan.landmarks import CanalLandmark
from ctdrill.imaging.plan.load import load_plan
from ctdrill.imaging.plan.protocol import generic_protocol
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.provenance import SeriesInfo
from ctdrill.imaging.sampling.walls import BISECT_TOL_MM, DEPTH_STEP_MM
from ctdrill.imaging.volume import CTVolume
from ctdrill.model.calibration import load_calibration

SP = 0.4
G = 400.0  # HU per mm inside the bone
PARALLEL = ImplantSpec("parallel 4.1 x 10", 4.1, 10.0, 4.1, "flat")
R = 2.05  # its radius
PILOT = DrillSpec(2.0, 0.6)
#: An arc of the arch, its centre 60 mm lingual (-x) of the implants: buccal is +x there.
ARCH = np.array([[-60.0 + 60.0 * math.cos(a), 60.0 * math.sin(a), -6.0] for a in (-0.4, 0.0, 0.4)])
CONTEXT = CaseContext(DEFAULTS, series_uid="1.2.3", clearance_accuracy_mm=0.2)


@pytest.fixture(scope="module")
def calibration():  # type: ignore[no-untyped-def]
    return load_calibration("bone-literature")


def _slab(half_width: float) -> CTVolume:
    """Bone where ``|x| <= half_width`` and ``z <= 0`` (the crest), 0.4 mm voxels."""
    xs = np.arange(-12.0, 12.0 + 1e-9, SP)
    zs = np.arange(-24.0, 4.0 + 1e-9, SP)
    z, _y, x = np.meshgrid(zs, xs, xs, indexing="ij")
    inside = np.minimum(half_width - np.abs(x), -z)
    hu = np.clip(BONE_HU + G * inside, -1000.0, 3000.0).astype(np.float32)
    aff = np.eye(4)
    aff[:3, :3] *= SP
    aff[:3, 3] = [xs[0], xs[0], zs[0]]
    return CTVolume(hu, aff, None, SeriesInfo("1.2.826.0.1.3680043.2.1125.1"))


def _canal(x_mm: float, z_mm: float, radius_mm: float = 1.2) -> CanalLandmark:
    """A straight canal along y at (x, z)."""
    return CanalLandmark("ian", np.array([[x_mm, -30.0, z_mm], [x_mm, 30.0, z_mm]]), radius_mm)


def _plan(x_mm: float = 0.0, tilt_deg: float = 0.0, **kw: object) -> Plan:
    """Entry on the crest at (x, 0, 0), tilted towards +x; the apex 11 mm down the axis, the
    platform 1 mm below the entry."""
    t = math.radians(tilt_deg)
    u = np.array([math.sin(t), 0.0, -math.cos(t)])
    entry = np.array([x_mm, 0.0, 0.0])
    kw.setdefault("drill", PILOT)
    return Plan(entry, entry + 11.0 * u, implant=PARALLEL, **kw)  # type: ignore[arg-type]


def _codes(summary: object) -> list[str]:
    return [w.code for w in summary.warnings]  # type: ignore[attr-defined]


def test_vertical_implant_beside_a_straight_canal(calibration) -> None:  # type: ignore[no-untyped-def]
    vol = _slab(9.0)
    for gap in (4.5, 6.0):
        plan = _plan(landmarks=(_canal(gap, -6.0),))
        path = plan_path(vol, plan.drilled(0), calibration)
        s = job_summary(path, CONTEXT).summary
        # the body: the gap less the canal's and the implant's radii; the drill: its own
        assert s.outcome.implant_clearance_mm == pytest.approx(gap - 1.2 - R, abs=1e-4)
        assert s.outcome.plan_clearance_mm == pytest.approx(gap - 1.2 - 1.0, abs=1e-4)
        binding = s.outcome.implant_binding_landmark
        assert binding is not None and (binding.name, binding.margin_mm) == ("ian", 2.0)
        codes = _codes(s)
        if gap - 1.2 - R < 2.0:  # 1.25 mm: the implant breaks the margin, the drill does not
            assert "implant_violates_margin" in codes
            (msg,) = [w.message for w in s.warnings if w.code == "plan_violates_margin"]
            assert "implant body" in msg
        else:
            assert "implant_violates_margin" not in codes and "plan_violates_margin" not in codes
        assert "thin_wall" not in codes and "cortical_perforation" not in codes


def test_an_implant_in_a_slab_of_known_width(calibration) -> None:  # type: ignore[no-untyped-def]
    vol = _slab(3.5)
    plan = _plan(0.3, arch_lps=ARCH)
    s = job_summary(plan_path(vol, plan.drilled(0), calibration), CONTEXT).summary
    walls = s.outcome.bone_walls
    assert walls is not None
    buccal, lingual = 3.5 - 0.3 - R, 3.5 + 0.3 - R  # the half-width less the radius
    assert walls.buccal_mm == pytest.approx(buccal, abs=BISECT_TOL_MM)
    assert walls.lingual_mm == pytest.approx(lingual, abs=BISECT_TOL_MM)
    assert walls.min_mm == pytest.approx(buccal, abs=BISECT_TOL_MM)
    assert walls.direction_lps == pytest.approx((1.0, 0.0, 0.0), abs=1e-12)
    assert walls.perforation is None
    # along the slab (+-y) bone outlasts the CT (12 mm) before the 10 mm rays end: unknown,
    # never counted as bone
    assert 0.0 < walls.unknown_fraction < 0.2 and "unknown" in walls.outside_ct
    codes = _codes(s)
    assert "thin_wall" in codes and "cortical_perforation" not in codes  # 1.15 < 1.5 mm
    assert "bone_walls_unknown" in codes
    assert s.outcome.implant_clearance_mm is None  # no landmark: nothing to measure against
    # a plan asking for thinner walls accepts it
    relaxed = _plan(0.3, arch_lps=ARCH, min_wall_mm=1.0)
    assert "thin_wall" not in (implant_outcome(vol, relaxed) or _fail()).codes


def _fail() -> object:
    raise AssertionError("no outcome")


def test_a_tilted_implant_leaving_the_slab_perforates(calibration) -> None:  # type: ignore[no-untyped-def]
    vol = _slab(3.5)
    tilt = 20.0
    plan = _plan(tilt_deg=tilt, arch_lps=ARCH)
    s = job_summary(plan_path(vol, plan.drilled(0), calibration), CONTEXT).summary
    assert "cortical_perforation" in _codes(s)
    walls = s.outcome.bone_walls
    assert walls is not None and walls.perforation is not None and walls.min_mm == 0.0
    # the buccal side leaves the slab where s sin t + R cos t = 3.5 (s along the axis from
    # the entry; the platform is 1 mm down it): the first exposed sample of the depth grid
    t = math.radians(tilt)
    leaves = (3.5 - R * math.cos(t)) / math.sin(t) - 1.0
    first = walls.perforation.below_platform_mm[0]
    assert leaves < first <= leaves + DEPTH_STEP_MM + 1e-9
    # buccal: +x, perpendicular to the tilted axis
    buccal = np.array([math.cos(t), 0.0, math.sin(t)])
    assert float(np.dot(walls.perforation.direction_lps, buccal)) > 0.99
    facts = implant_facts(vol, plan)
    assert facts is not None and facts.angulation_deg == pytest.approx(tilt, abs=1e-9)
    # upright, the same implant stays in bone
    upright = implant_outcome(vol, _plan(arch_lps=ARCH))
    assert upright is not None and "cortical_perforation" not in upright.codes


def test_every_drill_is_drilled_to_the_apex_plus_its_tip(calibration, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """A protocol plan above a canal: each drill's planned depth is the apex's (11 mm) plus
    its own tip, and its planned clearance is the canal's top less that depth."""
    vol = _slab(9.0)
    top = 16.0 - 1.2  # the canal's top, 14.8 mm below the crest
    plan = _plan(landmarks=(_canal(0.0, -16.0),)).with_drills(generic_protocol(4.1))
    seq = plan_sequence(vol, plan, calibration)
    assert len(seq.steps) == 3
    for step, drill in zip(seq.steps, plan.drills, strict=True):
        assert step.planned_depth_mm == pytest.approx(11.0 + drill.tip_length_mm, abs=1e-9)
        assert step.plan_clearance_mm == pytest.approx(top - step.planned_depth_mm, abs=1e-6)
        assert step.implant is seq.steps[0].implant  # computed once for the sequence
    listing = sequence_summary(seq, CONTEXT)
    depths = [d.planned_depth_mm for d in listing.drills]
    assert depths == pytest.approx([11.0 + d.tip_length_mm for d in plan.drills], abs=1e-4)
    assert listing.outcome.target_lps == pytest.approx((0.0, 0.0, -11.0))  # the apex
    assert listing.outcome.overdrill_mm == plan.drills[-1].tip_length_mm
    # the flat apex face 3.8 mm above the canal's top
    assert listing.outcome.implant_clearance_mm == pytest.approx(top - 11.0, abs=1e-4)
    facts = implant_facts(vol, plan)
    assert facts is not None
    assert [d.drilled_depth_mm for d in facts.drills] == pytest.approx(depths, abs=1e-4)
    assert facts.angulation_deg == 0.0
    assert facts.crest_depth_mm == pytest.approx(0.0, abs=1e-6)
    assert facts.canal_depth_mm == pytest.approx(top, abs=2e-4) and facts.axis_meets_canal
    assert facts.bone_height_mm == pytest.approx(top, abs=2e-4)
    assert facts.nerve == "ian" and facts.nerve_mm == pytest.approx(top - 11.0, abs=1e-6)
    # a plan file with the implant and no drill drills that protocol, and says so
    doc = {
        "format": "ctdrill-plan/1",
        "coordinate_system": "LPS",
        "entry_mm": [0.0, 0.0, 0.0],
        "target_mm": [0.0, 0.0, -11.0],
        "implant": {
            **PARALLEL.to_json(),
            "drills": [
                {"diameter_mm": d.diameter_mm, "tip_length_mm": d.tip_length_mm}
                for d in plan.drills
            ],
        },
        "landmarks": [plan.landmarks[0].to_plan_item()],
    }
    (tmp_path / "p.json").write_text(json.dumps(doc), encoding="utf-8")
    read = load_plan(tmp_path / "p.json")
    assert read.drills == plan.drills
    listing = sequence_summary(plan_sequence(vol, read, calibration), CONTEXT)
    assert "implant_protocol" in [w.code for w in listing.warnings]
    assert [d.planned_depth_mm for d in listing.drills] == pytest.approx(depths, abs=1e-4)
    # a drill deep enough to break the margin is reported at its drilled depth
    deep = _plan(landmarks=(_canal(0.0, -15.0),))  # top 13.8: drill tip at 11.6, 2.2 mm off
    path = plan_path(vol, deep.drilled(0), calibration)
    assert path.plan_clearance_mm == pytest.approx(13.8 - 11.6, abs=1e-6)
    assert path.planned_depth_mm == pytest.approx(11.6, abs=1e-9)
    assert job_summary(path, CONTEXT).summary.outcome.implant.seated  # type: ignore[union-attr]
    # the margin stops the tip between the apex and the drilled depth (canal top 13.3 mm: safe
    # to 11.3 mm); its full diameter then ends 0.6 mm higher, above the apex: not seated
    short = plan_path(vol, _plan(landmarks=(_canal(0.0, -14.5),)).drilled(0), calibration)
    assert short.stop_reason == "margin"
    assert short.stop_depth_mm == pytest.approx(13.3 - 2.0, abs=1e-3)
    s = job_summary(short, CONTEXT).summary
    assert s.outcome.implant is not None and not s.outcome.implant.seated
    (msg,) = [w.message for w in s.warnings if w.code == "implant_beyond_stop"]
    assert "its full diameter to 10.70 mm, 0.6 mm above its tip" in msg
