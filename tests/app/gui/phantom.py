"""An in-memory jaw-like phantom with exactly known geometry, for the GUI tests.

A bone bar runs along patient left (x): elliptical cross-section in (y, z) with a 1.5 mm
cortical shell (1500 HU) around trabecular bone (500 HU), air (-1000 HU) around it, and a canal
(radius 1.2 mm, 30 HU) along the bar. Voxels are 0.5 mm, identity orientation.
"""

from __future__ import annotations

import numpy as np

from ctdrill.imaging import CTVolume, SeriesInfo

SPACING_MM = 0.5
SHAPE_KJI = (60, 80, 100)  # slices (z), rows (y), cols (x)
ORIGIN_LPS = np.array([-25.0, -20.0, -15.0])
#: Bone bar: centre (y, z) and semi-axes, mm.
BAR_CENTER_YZ = (0.0, 0.0)
BAR_SEMI_YZ = (8.0, 11.0)
CORTEX_MM = 1.5
#: Canal centreline: along x at (y, z), radius.
CANAL_YZ = (0.0, -4.0)
CANAL_RADIUS_MM = 1.2
BONE_TOP_Z = BAR_CENTER_YZ[1] + BAR_SEMI_YZ[1]


def phantom_volume() -> CTVolume:
    """The phantom as a CTVolume (int16 HU)."""
    nk, nj, ni = SHAPE_KJI
    z = ORIGIN_LPS[2] + SPACING_MM * np.arange(nk)
    y = ORIGIN_LPS[1] + SPACING_MM * np.arange(nj)
    zz, yy = np.meshgrid(z, y, indexing="ij")
    r = np.sqrt(
        ((yy - BAR_CENTER_YZ[0]) / BAR_SEMI_YZ[0]) ** 2
        + ((zz - BAR_CENTER_YZ[1]) / BAR_SEMI_YZ[1]) ** 2
    )
    inner = np.sqrt(
        ((yy - BAR_CENTER_YZ[0]) / (BAR_SEMI_YZ[0] - CORTEX_MM)) ** 2
        + ((zz - BAR_CENTER_YZ[1]) / (BAR_SEMI_YZ[1] - CORTEX_MM)) ** 2
    )
    plane = np.full((nk, nj), -1000, dtype=np.int16)
    plane[r <= 1.0] = 1500
    plane[inner <= 1.0] = 500
    canal = np.hypot(yy - CANAL_YZ[0], zz - CANAL_YZ[1]) <= CANAL_RADIUS_MM
    plane[canal] = 30
    hu = np.repeat(plane[:, :, None], ni, axis=2)
    affine = np.eye(4)
    affine[:3, :3] *= SPACING_MM
    affine[:3, 3] = ORIGIN_LPS
    return CTVolume(hu=hu, affine_lps=affine, valid=None, info=SeriesInfo(series_uid="1.2.3"))
