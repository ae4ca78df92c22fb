"""The rules a volume file's voxel grid must meet: one owner for NIfTI, NRRD, MetaImage, DICOM SEG.

A grid is the affine ``(i, j, k, 1) -> LPS mm`` of a file's voxels (i fastest in the file). It
is a *proper grid*, and the file's geometry is taken exactly, when:

- every number of it is finite;
- each axis step (the affine's column norm, the voxel spacing) lies in
  [:data:`MIN_SPACING_MM`, :data:`MAX_SPACING_MM`];
- the in-plane axes i and j are perpendicular: the cosine of their angle is at most
  :data:`ORIENTATION_TOL` (1e-4: 0.006 deg, 5 um across 50 mm);
- the slice axis k leans off the i x j normal by at most :data:`MAX_TILT_DEG` (a gantry tilt
  keeps its shear, as a DICOM series does; more than 0.1 deg is reported as ``gantry_tilt``);
- every voxel corner lies within :data:`MAX_WORLD_MM` of the origin.

Direction cosines given as such (DICOM ``ImageOrientationPatient``, MetaImage
``TransformMatrix``) must in addition be unit vectors to :data:`ORIENTATION_TOL`: a vector of
length 10 is not rescaled silently, it is refused (:func:`check_direction_cosines`).

Two descriptions of one grid (a NIfTI qform and sform) are the same grid when they place every
voxel corner within :data:`SAME_GRID_MM` of each other (:func:`grid_distance_mm`): the
tolerance under which a DICOM stack counts as regular (:data:`ctdrill.imaging.stack.AFFINE_TOL_MM`).
"""

from __future__ import annotations

import itertools

import numpy as np

from ctdrill.imaging.bounds import MAX_COORDINATE_MM
from ctdrill.imaging.stack import AFFINE_TOL_MM

#: Largest |cos| between the in-plane axes, and largest |length - 1| of a direction cosine.
ORIENTATION_TOL = 1e-4
#: Voxel spacing bounds, mm (1 um is finer than any micro-CT; 100 mm is no CT's voxel).
MIN_SPACING_MM = 1e-3
MAX_SPACING_MM = 100.0
#: Farthest voxel corner from the LPS origin, mm (the world frame's bound, shared with plans).
MAX_WORLD_MM = MAX_COORDINATE_MM
#: Largest lean of the slice axis off the in-plane normal, degrees (gantry tilts reach ~30).
MAX_TILT_DEG = 45.0
#: The lean above which the grid is reported as tilted (:mod:`ctdrill.imaging.dicom.geometry`).
TILT_REPORT_DEG = 0.1
#: Two mappings of one grid closer than this on every voxel corner are the same grid, mm.
SAME_GRID_MM = AFFINE_TOL_MM
#: LPS from RAS (and back): x and y negated.
RAS_TO_LPS = np.diag([-1.0, -1.0, 1.0, 1.0])

ErrorType = type[Exception]


def grid_corners_lps(affine_lps: np.ndarray, shape_kji: tuple[int, ...]) -> np.ndarray:
    """(8, 3) LPS mm of the corners of the voxel boxes' hull (index -1/2 .. n - 1/2).

    Any affine function of position is extreme on these, so a bound or a distance checked on
    them holds on every voxel corner.
    """
    n_k, n_j, n_i = (int(n) for n in shape_kji[-3:])
    ranges = [(-0.5, n_i - 0.5), (-0.5, n_j - 0.5), (-0.5, n_k - 0.5)]
    ijk = np.array(list(itertools.product(*ranges)), dtype=np.float64)
    a = np.asarray(affine_lps, dtype=np.float64)
    out: np.ndarray = ijk @ a[:3, :3].T + a[:3, 3]
    return out


def grid_distance_mm(a: np.ndarray, b: np.ndarray, shape_kji: tuple[int, ...]) -> float:
    """Largest distance, mm, between where ``a`` and ``b`` put a voxel corner of the grid."""
    with np.errstate(all="ignore"):
        d = grid_corners_lps(a, shape_kji) - grid_corners_lps(b, shape_kji)
        dist = float(np.max(np.linalg.norm(d, axis=1)))
    return dist if np.isfinite(dist) else float("inf")


def column_lengths(matrix: np.ndarray) -> np.ndarray:
    """Euclidean length of each column, without overflow for huge entries (1e300 stays 1e300)."""
    m = np.asarray(matrix, dtype=np.float64)
    scale = np.max(np.abs(m), axis=0)
    safe = np.where(scale > 0, scale, 1.0)
    out: np.ndarray = np.linalg.norm(m / safe, axis=0) * scale
    return out


def tilt_deg(affine_lps: np.ndarray) -> float:
    """Angle between the affine's k column and the normal of its i and j columns, degrees."""
    a = np.asarray(affine_lps, dtype=np.float64)[:3, :3]
    normal = np.cross(a[:, 0], a[:, 1])
    cos = abs(float(a[:, 2] @ normal)) / float(np.linalg.norm(a[:, 2]) * np.linalg.norm(normal))
    return float(np.degrees(np.arccos(min(1.0, cos))))


def check_direction_cosines(
    vectors: np.ndarray, *, where: str, field: str, error: ErrorType
) -> np.ndarray:
    """Refuse direction cosines that are not unit, mutually perpendicular vectors.

    Parameters
    ----------
    vectors : (n, 3) the axes' directions as the file gives them.
    where, field : the file and the field, for the message.
    error : the exception type raised.

    Returns
    -------
    (n, 3) float64, the vectors as given (within tolerance of unit length).
    """
    v = np.asarray(vectors, dtype=np.float64)
    if not np.all(np.isfinite(v)):
        raise error(f"{where}: {field} {_fmt(v)} is not finite; the orientation cannot be known")
    norms = np.linalg.norm(v, axis=1)
    worst = int(np.argmax(np.abs(norms - 1.0)))
    if abs(norms[worst] - 1.0) > ORIENTATION_TOL:
        raise error(
            f"{where}: {field}: direction {worst + 1} has length {norms[worst]:.6g}, not 1 "
            f"(tolerance {ORIENTATION_TOL:g}); direction cosines are unit vectors: the file's "
            "geometry is damaged, export it again"
        )
    for a, b in itertools.combinations(range(len(v)), 2):
        cos = float(v[a] @ v[b]) / float(norms[a] * norms[b])
        if abs(cos) > ORIENTATION_TOL:
            raise error(
                f"{where}: {field}: directions {a + 1} and {b + 1} are not perpendicular "
                f"(cosine {cos:.6g}, tolerance {ORIENTATION_TOL:g}); the grid is not a proper "
                "voxel grid: export it again"
            )
    return v


def check_grid(
    affine_lps: np.ndarray,
    shape_kji: tuple[int, ...],
    *,
    where: str,
    field: str,
    error: ErrorType,
) -> float:
    """Refuse an affine that is not a proper grid (module docstring); return its tilt, degrees.

    Parameters
    ----------
    affine_lps : (4, 4) ``(i, j, k, 1) -> LPS mm``.
    shape_kji : the voxel array's shape, its last three axes (k, j, i).
    where, field : the file and the header field(s) the affine came from, for the message.
    error : the exception type raised.
    """
    a = np.asarray(affine_lps, dtype=np.float64)
    if a.shape != (4, 4) or not np.all(np.isfinite(a)):
        raise error(f"{where}: {field} is not finite ({_fmt(a[:3])}); the geometry cannot be known")
    spacing = column_lengths(a[:3, :3])
    for axis, sp in zip("ijk", spacing, strict=True):
        if not MIN_SPACING_MM <= sp <= MAX_SPACING_MM:
            raise error(
                f"{where}: {field}: the voxel spacing along {axis} is {sp:.6g} mm, outside "
                f"{MIN_SPACING_MM:g}..{MAX_SPACING_MM:g} mm; the geometry is damaged"
            )
    e_i, e_j = a[:3, 0] / spacing[0], a[:3, 1] / spacing[1]  # spacing >= MIN_SPACING_MM
    cos = float(e_i @ e_j)
    if abs(cos) > ORIENTATION_TOL:
        raise error(
            f"{where}: {field}: the i and j axes are not perpendicular (cosine {cos:.6g}, "
            f"tolerance {ORIENTATION_TOL:g}); the grid is not a proper voxel grid: export it "
            "again"
        )
    lean = tilt_deg(a)
    if lean > MAX_TILT_DEG:
        raise error(
            f"{where}: {field}: the slice axis leans {lean:.3g} deg off the slice normal (at "
            f"most {MAX_TILT_DEG:g}); the grid is not a proper voxel grid: export it again"
        )
    far = float(np.max(np.abs(grid_corners_lps(a, shape_kji))))
    if far > MAX_WORLD_MM:
        raise error(
            f"{where}: {field}: voxels reach {far:.6g} mm from the origin (at most "
            f"{MAX_WORLD_MM:g}); the origin or the spacing is damaged"
        )
    return lean


def _fmt(values: np.ndarray) -> str:
    flat = np.asarray(values, dtype=np.float64).reshape(-1)
    text = ", ".join(f"{v:.6g}" for v in flat[:12])
    return f"[{text}{', ...' if flat.size > 12 else ''}]"
