"""A ridge beside a thin cortical plate: the densest axis perforates (tests of ``suggest``).

LPS mm, 0.5 mm voxels with centres at odd multiples of 0.25 (x in [-9.75, 9.75], y in
[-13.75, 13.75], z in [-15.75, 2.75]). Air (-1000 HU) above z = 0; below it soft tissue
(40 HU) except

- the ridge, trabecular bone (600 HU, Misch D3), voxel centres ``-4.5 < x < 4.5``;
- the plate, cortical bone (1800 HU), voxel centres ``4.5 < x < 7``: 2.5 mm thick, thinner
  than the 4.1 mm implant.

Everything is uniform in y and, below z = -0.25, in z; HU is linear in x between voxel
centres (trilinear), so the bone edge (150 HU) lies at :data:`X_LEFT` and :data:`X_RIGHT`
in closed form, and a vertical implant of radius ``r`` on the axis ``x = x_c`` has the
thinnest wall ``min(X_RIGHT - x_c - r, x_c - r - X_LEFT)`` (along -x or +x: a ray at angle
``t`` off the x axis travels ``1 / cos t`` as far), and perforates (its surface crosses an
edge) when that is negative.

The plan: a parallel 4.1 x 8 mm implant (flat apex, the generic protocol's three drills)
vertical from the origin, apex 8.5 mm deep (the platform 0.5 mm below the entry).
"""

from __future__ import annotations

import numpy as np

from ctdrill.imaging.misch import BONE_HU
from ctdrill.imaging.plan.implants import load_implant_library
from ctdrill.imaging.plan.landmarks import CanalLandmark
from ctdrill.imaging.plan.types import Plan
from ctdrill.imaging.volume import CTVolume, SeriesInfo

VOXEL_MM = 0.5
AIR, SOFT, RIDGE_HU, PLATE_HU = -1000, 40, 600, 1800  # the plate below teeth (2000 HU)
RIDGE_X, PLATE_X = 4.5, 7.0
DEPTH_MM = 8.5
IMPLANT = "parallel 4.1 x 8"
#: The bone edge along x: 150 HU between the last bone centre and the first soft-tissue one.
X_LEFT = -4.25 - (RIDGE_HU - BONE_HU) / (RIDGE_HU - SOFT) * VOXEL_MM
X_RIGHT = 6.75 + (PLATE_HU - BONE_HU) / (PLATE_HU - SOFT) * VOXEL_MM


def plate_volume() -> CTVolume:
    """The volume described in the module docstring."""
    xs = np.arange(-9.75, 9.76, VOXEL_MM)
    ys = np.arange(-13.75, 13.76, VOXEL_MM)
    zs = np.arange(-15.75, 2.76, VOXEL_MM)
    z, _, x = np.meshgrid(zs, ys, xs, indexing="ij")
    hu = np.full(z.shape, SOFT, dtype=np.int16)
    hu[np.abs(x) < RIDGE_X] = RIDGE_HU
    hu[(x > RIDGE_X) & (x < PLATE_X)] = PLATE_HU
    hu[z > 0] = AIR
    aff = np.diag([VOXEL_MM, VOXEL_MM, VOXEL_MM, 1.0])
    aff[:3, 3] = [xs[0], ys[0], zs[0]]
    return CTVolume(hu=hu, affine_lps=aff, valid=None, info=SeriesInfo(series_uid="1.2.826.25"))


def plate_plan(landmarks: tuple[CanalLandmark, ...] = (), x_mm: float = 0.0) -> Plan:
    """The planned vertical axis at ``x = x_mm`` (entry at z = 0) with the implant and its
    protocol."""
    spec = next(s for s in load_implant_library() if s.name == IMPLANT)
    plan = Plan(
        entry_lps=np.array([x_mm, 0.0, 0.0]),
        target_lps=np.array([x_mm, 0.0, -DEPTH_MM]),
        calibration="bone-illustrative",
        margin_mm=2.0,
        landmarks=landmarks,
        name="plate",
        implant=spec,
    )
    return plan.with_drills(spec.drills)


def thinnest_wall_mm(x_c: float, radius_mm: float) -> float:
    """The thinnest wall around a vertical implant of ``radius_mm`` on ``x = x_c`` (module
    docstring; negative: it perforates)."""
    return min(X_RIGHT - x_c - radius_mm, x_c - radius_mm - X_LEFT)


def canal(z_mm: float = -12.5) -> CanalLandmark:
    """A canal along y under the ridge's middle (radius 1 mm)."""
    pts = np.array([[0.0, -30.0, z_mm], [0.0, 30.0, z_mm]])
    return CanalLandmark(name="canal", points_lps=pts, radius_mm=1.0)
