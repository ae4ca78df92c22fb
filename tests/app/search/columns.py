"""A synthetic jaw whose best feasible axis is known in closed form (tests of ``suggest``).

LPS mm, 0.25 mm voxels, x and y in [-9, 9], z in [-18, 4]. Air (-1000 HU) above the flat bone
surface z = 0, trabecular bone (400 HU, Misch D3) below it, and two vertical columns of
uniform density reaching the surface:

- column A at x = -2.5 (radius 1.5 mm), 2000 HU: the densest bone, but the canal (a line along
  y at x = -2.5, z = -6, radius 0.8 mm, margin 2 mm) runs under it: an axis must stay
  2 + 0.8 + 1 = 3.8 mm from that line, so every axis through A is infeasible;
- column B at x = +2.8 (radius 2.5 mm), 1400 HU (cortical, > 1250).

The planned axis is vertical from (0, 0, 0), 10 mm deep, drill 2 mm with a 0.6 mm tip, no
implant: the score reads the shells 0.25 and 0.75 mm outside the drill's osteotomy (radius
1 mm). Among vertical axes the best are those whose shells stay inside B (the axis within
2.5 - 1.75 = 0.75 mm of B's centre): the top ring lies on the bone surface (150 HU, the
trilinear crossing of the one-voxel ramp between the voxel centres z = +0.125, air, and
z = -0.125, B) and every deeper one in B's 1400 HU (:func:`best_terms`).
"""

from __future__ import annotations

import numpy as np

from ctdrill.imaging.misch import BONE_HU, CORTICAL_HU
from ctdrill.imaging.plan.landmarks import CanalLandmark
from ctdrill.imaging.plan.types import DrillSpec, Plan
from ctdrill.imaging.volume import CTVolume, SeriesInfo

VOXEL_MM = 0.25
AIR, TRABECULAR, A_HU, B_HU = -1000, 400, 2000, 1400
A_X, A_R = -2.5, 1.5
B_X, B_R = 2.8, 2.5
CANAL_X, CANAL_Z, CANAL_R = -2.5, -6.0, 0.8
DEPTH_MM = 10.0
DRILL = DrillSpec(diameter_mm=2.0, tip_length_mm=0.6, blades=2, rpm=900.0)


def columns_volume() -> CTVolume:
    """The volume described in the module docstring."""
    xs = np.arange(-9.0, 9.0 + 1e-9, VOXEL_MM)
    zs = np.arange(-18.0 + VOXEL_MM / 2, 4.0, VOXEL_MM)  # centres at +-0.125 around z = 0
    z, y, x = np.meshgrid(zs, xs, xs, indexing="ij")
    hu = np.full(z.shape, TRABECULAR, dtype=np.int16)
    hu[np.hypot(x - A_X, y) <= A_R] = A_HU
    hu[np.hypot(x - B_X, y) <= B_R] = B_HU
    hu[z > 0] = AIR
    aff = np.diag([VOXEL_MM, VOXEL_MM, VOXEL_MM, 1.0])
    aff[:3, 3] = [xs[0], xs[0], zs[0]]
    return CTVolume(hu=hu, affine_lps=aff, valid=None, info=SeriesInfo(series_uid="1.2.826.7"))


def canal(margin_mm: float | None = None) -> CanalLandmark:
    """The canal under column A."""
    return CanalLandmark(
        name="canal",
        points_lps=np.array([[CANAL_X, -30.0, CANAL_Z], [CANAL_X, 30.0, CANAL_Z]]),
        radius_mm=CANAL_R,
        margin_mm=margin_mm,
    )


def columns_plan(landmarks: tuple[CanalLandmark, ...] | None = None) -> Plan:
    """The planned vertical axis from the origin, 10 mm deep, with the canal."""
    return Plan(
        entry_lps=np.zeros(3),
        target_lps=np.array([0.0, 0.0, -DEPTH_MM]),
        drill=DRILL,
        calibration="bone-illustrative",
        margin_mm=2.0,
        landmarks=(canal(),) if landmarks is None else landmarks,
        name="columns",
    )


def best_terms() -> tuple[float, float, float, float]:
    """(body_hu, crest_cortical, apex_cortical, entry_z) of a vertical axis whose shells stay
    inside B, in closed form: the body's depths every 0.5 mm from 0 to 10 mm
    (:data:`~ctdrill.app.search.shell.DEPTH_STEP_MM`), the ring at depth 0 on the surface
    (150 HU), the others at B_HU; crest zone depths <= 2 mm, apex zone >= 8 mm."""
    from ctdrill.app.search.shell import DEPTH_STEP_MM

    depth = np.linspace(0.0, DEPTH_MM, round(DEPTH_MM / DEPTH_STEP_MM) + 1)
    hu = np.where(depth == 0.0, BONE_HU, B_HU).astype(np.float64)
    crest = float(np.mean(hu[depth <= 2.0 + 1e-9] > CORTICAL_HU))
    apex = float(np.mean(hu[depth >= DEPTH_MM - 2.0 - 1e-9] > CORTICAL_HU))
    entry_z = VOXEL_MM / 2 - (BONE_HU - AIR) / (B_HU - AIR) * VOXEL_MM
    return float(hu.mean()), crest, apex, float(entry_z)
