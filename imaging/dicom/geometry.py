"""Stack geometry from ImagePositionPatient / ImageOrientationPatient / PixelSpacing only.

Slices are ordered by IPP projected on the IOP normal. The affine's k column is the least-squares
IPP step per unit normal distance times the nominal (median) normal step, so a gantry-tilted
stack keeps its shear; the true positions travel with it (``positions_mm``) and every mapping of
:class:`~ctdrill.imaging.volume.CTVolume` uses them. The irregular-step rule is
:mod:`ctdrill.imaging.stack`'s. SliceThickness is never used for geometry (except for a single
slice, where nothing else exists).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ctdrill.imaging.dicom.discovery import SliceHeader
from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.stack import GAP_FACTOR, irregular_steps, nominal_step_mm, wide_steps
from ctdrill.imaging.volume import LoadWarning

#: Two planes closer than this along the normal are at the same position, mm.
SAME_POSITION_TOL_MM = 0.01
#: A step within this fraction of an integer multiple (>= 2) of the median is a gap.
GAP_TOL = 0.1
#: Angle between the IPP step and the slice normal above which the stack is tilted, degrees.
TILT_TOL_DEG = 0.1


class GeometryInputError(ImagingInputError):
    """The slice geometry cannot make a volume."""


@dataclass(frozen=True)
class StackGeometry:
    """The geometry of an ordered stack.

    Attributes
    ----------
    affine_lps : np.ndarray
        (4, 4) ``(i=col, j=row, k=slice, 1)`` -> LPS mm.
    positions_mm : np.ndarray
        (slices,) IPP projected on the slice normal, mm (ascending).
    tilt_deg : float
        Angle between the k column and the slice normal.
    warnings : tuple[LoadWarning, ...]
        ``gantry_tilt``, ``slice_gap``, ``nonuniform_spacing``, ``single_slice``.
    """

    affine_lps: np.ndarray
    positions_mm: np.ndarray
    tilt_deg: float
    warnings: tuple[LoadWarning, ...]


def require_geometry(h: SliceHeader) -> None:
    """Refuse a plane without IPP, IOP or PixelSpacing, naming the file and the tag."""
    where = f"{h.path}" + (f" frame {h.frame + 1}" if h.n_frames > 1 else "")
    for name, value in (
        ("ImagePositionPatient", h.ipp),
        ("ImageOrientationPatient", h.iop),
        ("PixelSpacing", h.pixel_spacing),
    ):
        if value is None:
            raise GeometryInputError(
                f"{where}: missing or malformed {name}; the geometry cannot be known "
                "(re-export the series from the scanner with full geometry)"
            )
    assert h.pixel_spacing is not None and h.iop is not None and h.ipp is not None
    for name, value in (
        ("ImagePositionPatient", h.ipp),
        ("ImageOrientationPatient", h.iop),
        ("PixelSpacing", h.pixel_spacing),
    ):
        if not all(np.isfinite(value)):
            raise GeometryInputError(
                f"{where}: {name} {list(value)} is not finite; the geometry cannot be known"
            )
    if min(h.pixel_spacing) <= 0:
        raise GeometryInputError(f"{where}: PixelSpacing {h.pixel_spacing} must be positive")
    r, c = np.array(h.iop[:3]), np.array(h.iop[3:])
    if (
        abs(np.linalg.norm(r) - 1) > 0.01
        or abs(np.linalg.norm(c) - 1) > 0.01
        or abs(float(r @ c)) > 0.01
    ):
        raise GeometryInputError(
            f"{where}: ImageOrientationPatient {h.iop} is not two orthonormal directions"
        )


def orientation_key(h: SliceHeader) -> tuple[int, ...]:
    """IOP rounded for grouping planes into one spatial stack (~0.06 degree)."""
    assert h.iop is not None
    return tuple(round(v * 1000) for v in h.iop)


def frame_axes(h: SliceHeader) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit row direction, column direction and normal (row x column) of a plane."""
    assert h.iop is not None
    r = np.array(h.iop[:3], dtype=np.float64)
    c = np.array(h.iop[3:], dtype=np.float64)
    r /= np.linalg.norm(r)
    c -= (c @ r) * r
    c /= np.linalg.norm(c)
    return r, c, np.cross(r, c)


def group_positions(planes: Sequence[SliceHeader], normal: np.ndarray) -> list[list[SliceHeader]]:
    """Planes sorted along ``normal``, grouped by equal position (duplicates share a group)."""
    pos = np.array([np.asarray(p.ipp) @ normal for p in planes])
    order = np.argsort(pos, kind="stable")
    groups: list[list[SliceHeader]] = []
    last = -np.inf
    for idx in order:
        if groups and pos[idx] - last <= SAME_POSITION_TOL_MM:
            groups[-1].append(planes[int(idx)])
        else:
            groups.append([planes[int(idx)]])
            last = pos[idx]
    return groups


def stack_geometry(planes: Sequence[SliceHeader]) -> StackGeometry:
    """Affine, positions and geometry warnings of planes already ordered along the normal."""
    first = planes[0]
    r, c, n = frame_axes(first)
    assert first.pixel_spacing is not None
    row_sp, col_sp = first.pixel_spacing
    ipp = np.array([p.ipp for p in planes], dtype=np.float64)
    pos = ipp @ n
    warnings: list[LoadWarning] = []
    tilt = 0.0
    if len(planes) == 1:
        thick = first.meta.get("spacing_between_slices_mm") or first.meta.get("slice_thickness_mm")
        step = float(thick) if thick and thick > 0 else 1.0
        kcol = n * step
        warnings.append(
            LoadWarning(
                "single_slice",
                f"one slice only: not a volume for the force path (k spacing {step:g} mm "
                "taken from SliceThickness)",
            )
        )
    else:
        steps = np.diff(pos)
        med = nominal_step_mm(pos)
        # IPP as a linear function of the normal position: ipp = a + b * pos.
        rel = pos - pos[0]
        b = (ipp - ipp[0]).T @ rel / float(rel @ rel)
        fit = ipp[0] + np.outer(rel, b)
        resid = float(np.max(np.linalg.norm(ipp - fit, axis=1)))
        tol = max(0.05, 0.1 * min(row_sp, col_sp))
        if resid > tol:
            worst = planes[int(np.argmax(np.linalg.norm(ipp - fit, axis=1)))]
            raise GeometryInputError(
                f"{worst.path}: ImagePositionPatient is {resid:.3g} mm off the line through "
                "the other slices; the stack is not a regular volume (check the series)"
            )
        kcol = b * med
        cos = abs(float(kcol @ n)) / float(np.linalg.norm(kcol))
        tilt = float(np.degrees(np.arccos(min(1.0, cos))))
        if tilt > TILT_TOL_DEG:
            tag = first.meta.get("gantry_tilt_deg")
            tag_txt = f" (GantryDetectorTilt {tag:g} deg)" if tag is not None else ""
            warnings.append(
                LoadWarning(
                    "gantry_tilt",
                    f"slices are sheared by {tilt:.2f} deg from the slice normal{tag_txt}; "
                    "the affine keeps the shear",
                )
            )
        ratio = steps / med
        nearest = np.rint(ratio)
        gap = (nearest >= 2) & (np.abs(ratio - nearest) <= GAP_TOL)
        odd = ~gap & irregular_steps(pos)
        wide = int(np.count_nonzero(wide_steps(pos)))
        drill_note = (
            f"; {wide} step(s) wider than {GAP_FACTOR:g} x the nominal step: a drill crossing "
            "one is refused unless gaps are interpolated explicitly"
            if wide
            else ""
        )
        if gap.any():
            missing = int(np.sum(nearest[gap] - 1))
            where = ", ".join(f"{pos[i]:.2f}..{pos[i + 1]:.2f}" for i in np.flatnonzero(gap))
            warnings.append(
                LoadWarning(
                    "slice_gap",
                    f"{missing} slice(s) missing (step {med:.4g} mm) between positions "
                    f"{where} mm along the normal; sampling uses the true positions"
                    f"{drill_note}",
                )
            )
        if odd.any():
            distinct = sorted({round(float(s), 2) for s in steps})
            warnings.append(
                LoadWarning(
                    "nonuniform_spacing",
                    f"slice steps {', '.join(f'{s:g}' for s in distinct)} mm (median "
                    f"{med:.4g} mm, {int(odd.sum())} irregular); the affine's k column is the "
                    "nominal step, sampling uses the true positions"
                    + ("" if gap.any() else drill_note),
                )
            )
    affine = np.eye(4)
    affine[:3, 0] = r * col_sp
    affine[:3, 1] = c * row_sp
    affine[:3, 2] = kcol
    affine[:3, 3] = ipp[0]
    return StackGeometry(affine, pos, tilt, tuple(warnings))
