"""The CT volume value: HU voxels, their LPS geometry, validity, provenance and load warnings.

Frames: ``affine_lps`` maps voxel indices ``(i=col, j=row, k=slice, 1)`` to DICOM patient LPS
millimetres for a regular stack. ``hu`` is indexed ``hu[k, j, i]`` (slices, rows, cols).

Slice positions are data: ``slice_positions_mm`` holds every slice's true position along the
slice normal, and :meth:`CTVolume.lps_to_index` / :meth:`CTVolume.index_to_lps` /
:meth:`CTVolume.sample` use them, so the continuous slice index ``k`` is piecewise linear in the
normal position between the two real neighbouring slices (exact for any spacing pattern, a
gantry tilt's shear included). For an irregular stack (:attr:`CTVolume.regular` False) the
affine's k column is the *nominal* (median) step along the stack's slice direction and only
slice 0 is placed by it; :attr:`CTVolume.slice_origins_lps` gives every slice's origin.

Sampling policy (:meth:`CTVolume.sample`): trilinear interpolation on the voxel centres.
A point is *inside* when its index coordinates lie in ``[0, n - 1]`` on every axis (the hull of
the voxel centres, no extrapolation); outside points get ``outside_hu``. Padding voxels
(``valid`` False) are **substituted by ``outside_hu``** before interpolation, so the stored
padding value (e.g. -2000 or -3024) never bleeds into a sample: next to padding a sample blends
towards ``outside_hu`` exactly as it would next to air. :meth:`CTVolume.inside` tells which
samples have a support entirely on valid voxels inside the grid.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from ctdrill.hu import AIR_HU
from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.provenance import WARNING_CODES, LoadWarning, SeriesInfo
from ctdrill.imaging.stack import is_regular, median, piecewise_linear, wide_steps

__all__ = ["WARNING_CODES", "CTVolume", "LoadWarning", "SeriesInfo"]

#: Tolerance, in voxels, for a point on the boundary of the voxel-centre hull.
_EDGE_TOL_VOX = 1e-6
#: Largest deviation, in slice steps, of a slice from the affine's position that is ignored.
_REGULAR_K_TOL = 1e-6
#: Corner bits (i, j, k) of the 8 trilinear corners.
_BI = np.array([0, 1, 0, 1, 0, 1, 0, 1], dtype=np.intp)
_BJ = np.array([0, 0, 1, 1, 0, 0, 1, 1], dtype=np.intp)
_BK = np.array([0, 0, 0, 0, 1, 1, 1, 1], dtype=np.intp)


def _readonly(arr: np.ndarray) -> np.ndarray:
    view = arr.view()
    view.flags.writeable = False
    return view


@dataclass(frozen=True, eq=False)
class CTVolume:
    """A CT volume in LPS millimetres.

    Attributes
    ----------
    hu : np.ndarray
        (slices, rows, cols) HU, int16 where exact else float32; read-only.
    affine_lps : np.ndarray
        (4, 4) float64: ``(i=col, j=row, k=slice, 1)`` -> LPS mm. May be sheared (gantry tilt).
        Exact for every slice only when :attr:`regular`; otherwise its k column is the nominal
        step and the mappings of this class use ``slice_positions_mm``.
    valid : np.ndarray | None
        (slices, rows, cols) bool, False on padding; None means every voxel is valid.
    info : SeriesInfo
        Provenance (no patient identifiers).
    warnings : tuple[LoadWarning, ...]
        What the loader noticed.
    slice_positions_mm : np.ndarray
        (slices,) true slice positions along the slice normal (IPP projected on the IOP
        normal), mm, strictly monotonic in the direction of the affine's k column, the first
        equal to the affine origin's. For a non-uniform stack the affine uses the nominal
        (median) step and these carry the truth: every LPS <-> index mapping uses them. Left
        empty, it is derived from the affine.
    """

    hu: np.ndarray
    affine_lps: np.ndarray
    valid: np.ndarray | None
    info: SeriesInfo
    warnings: tuple[LoadWarning, ...] = ()
    slice_positions_mm: np.ndarray = field(default_factory=lambda: np.empty(0))
    _inv_lin: np.ndarray = field(init=False, repr=False)
    _inv_off: np.ndarray = field(init=False, repr=False)
    _top: np.ndarray = field(init=False, repr=False)
    _max_lo: np.ndarray = field(init=False, repr=False)
    _strides: np.ndarray = field(init=False, repr=False)
    _corner_offsets: np.ndarray = field(init=False, repr=False)
    #: (slices,) slice positions in units of the affine's k column (0 for slice 0).
    _k_nominal: np.ndarray = field(init=False, repr=False)
    #: False when ``_k_nominal`` is exactly 0, 1, 2, ...: no remapping of k needed.
    _remap_k: bool = field(init=False, repr=False)

    def __post_init__(self) -> None:
        hu = np.asarray(self.hu)
        if hu.ndim != 3 or min(hu.shape) < 1:
            raise ImagingInputError(f"CTVolume.hu: expected (slices, rows, cols), got {hu.shape}")
        if hu.dtype not in (np.int16, np.float32):
            hu = hu.astype(np.float32)
        affine = np.array(self.affine_lps, dtype=np.float64)
        if affine.shape != (4, 4) or not np.all(np.isfinite(affine)):
            raise ImagingInputError("CTVolume.affine_lps: expected a finite (4, 4) matrix")
        if not np.allclose(affine[3], [0.0, 0.0, 0.0, 1.0]):
            raise ImagingInputError("CTVolume.affine_lps: last row must be [0, 0, 0, 1]")
        if abs(np.linalg.det(affine[:3, :3])) < 1e-12:
            raise ImagingInputError(
                "CTVolume.affine_lps: singular (zero spacing or collinear axes)"
            )
        valid = self.valid
        if valid is not None:
            valid = np.asarray(valid, dtype=bool)
            if valid.shape != hu.shape:
                raise ImagingInputError(
                    f"CTVolume.valid: shape {valid.shape} differs from hu {hu.shape}"
                )
            valid = None if bool(valid.all()) else _readonly(valid)
        positions = np.asarray(self.slice_positions_mm, dtype=np.float64).reshape(-1)
        normal = _unit_normal(affine)
        k_step_mm = float(affine[:3, 2] @ normal)  # normal distance per unit k; det != 0
        k_all = np.arange(hu.shape[0], dtype=np.float64)
        if positions.size == 0:
            positions = float(affine[:3, 3] @ normal) + k_all * k_step_mm
        elif positions.shape != (hu.shape[0],):
            raise ImagingInputError(
                f"CTVolume.slice_positions_mm: expected {hu.shape[0]} values, got {positions.size}"
            )
        k_nominal = (positions - positions[0]) / k_step_mm
        origin_pos = float(affine[:3, 3] @ normal)
        if not np.all(np.isfinite(positions)) or abs(positions[0] - origin_pos) > 1e-3:
            raise ImagingInputError(
                f"CTVolume.slice_positions_mm: the first position {positions[0]!r} mm must be "
                f"the affine origin's ({origin_pos:.6g} mm along the slice normal)"
            )
        if np.any(np.diff(k_nominal) <= 0.0):
            raise ImagingInputError(
                "CTVolume.slice_positions_mm: positions must run strictly in the direction of "
                "the affine's k column (ordered slices, none at the same position)"
            )
        # Within 1e-6 of a slice step of the regular positions (nanometres): regular, and
        # sampled without the remapping of k.
        remap = bool(np.max(np.abs(k_nominal - k_all)) > _REGULAR_K_TOL)
        object.__setattr__(self, "_k_nominal", _readonly(k_nominal if remap else k_all))
        object.__setattr__(self, "_remap_k", remap)
        object.__setattr__(self, "hu", _readonly(hu))
        object.__setattr__(self, "affine_lps", _readonly(affine))
        object.__setattr__(self, "valid", valid)
        object.__setattr__(self, "slice_positions_mm", _readonly(positions))
        object.__setattr__(self, "warnings", tuple(self.warnings))
        inv = np.linalg.inv(affine)
        object.__setattr__(self, "_inv_lin", inv[:3, :3].copy())
        object.__setattr__(self, "_inv_off", inv[:3, 3].copy())
        n_s, n_r, n_c = hu.shape
        sizes = np.array([n_c, n_r, n_s], dtype=np.intp)
        # Axes of size 1 get stride 0, so both corners along them are the same voxel.
        strides = np.where(sizes > 1, np.array([1, n_c, n_r * n_c], dtype=np.intp), 0)
        object.__setattr__(self, "_top", (sizes - 1).astype(np.float64))
        object.__setattr__(self, "_max_lo", np.maximum(sizes - 2, 0))
        object.__setattr__(self, "_strides", strides)
        object.__setattr__(
            self, "_corner_offsets", _BI * strides[0] + _BJ * strides[1] + _BK * strides[2]
        )

    # ------------------------------------------------------------------ geometry
    @property
    def dims(self) -> tuple[int, int, int]:
        """(cols, rows, slices)."""
        s, r, c = self.hu.shape
        return (int(c), int(r), int(s))

    @property
    def spacing_mm(self) -> tuple[float, float, float]:
        """(col, row, slice) distances in mm: the column norms of the affine."""
        norms = np.linalg.norm(self.affine_lps[:3, :3], axis=0)
        return (float(norms[0]), float(norms[1]), float(norms[2]))

    @property
    def is_volume(self) -> bool:
        """False for a single slice: not a volume for the force path."""
        return self.hu.shape[0] >= 2

    @property
    def warning_codes(self) -> tuple[str, ...]:
        """The codes of :attr:`warnings`, in order."""
        return tuple(w.code for w in self.warnings)

    def uniform_slices(self, *, rtol: float = 0.01) -> bool:
        """True when every slice step is within ``rtol`` of the median step."""
        steps = np.diff(self.slice_positions_mm)
        if steps.size == 0:
            return True
        med = median(steps)
        return bool(np.all(np.abs(steps - med) <= rtol * abs(med)))

    @cached_property
    def regular(self) -> bool:
        """True when ``affine_lps`` places every slice within ``stack.AFFINE_TOL_MM`` of its
        true position (:func:`ctdrill.imaging.stack.is_regular`)."""
        return is_regular(self.slice_positions_mm)

    @cached_property
    def has_slice_gaps(self) -> bool:
        """True when a slice step is wider than ``stack.GAP_FACTOR`` nominal steps
        (:func:`ctdrill.imaging.stack.wide_steps`)."""
        return bool(np.any(wide_steps(self.slice_positions_mm)))

    @property
    def slice_origins_lps(self) -> np.ndarray:
        """(slices, 3) LPS mm of voxel (0, 0) of every slice (its IPP), from the true
        positions: exact for any stack; with the affine's first two columns they place every
        voxel."""
        a = self.affine_lps
        return np.asarray(a[:3, 3][None, :] + self._k_nominal[:, None] * a[:3, 2][None, :])

    @property
    def affine_slice_index(self) -> np.ndarray:
        """(slices,) each slice's position in units of the affine's k column (0, then
        ``(p_k - p_0) / step``): equal to ``0, 1, 2, ...`` for a regular stack."""
        return self._k_nominal

    def _k_exact(self, k_affine: np.ndarray) -> np.ndarray:
        """Affine k (nominal steps from slice 0) -> true continuous slice index."""
        if not self._remap_k:
            return k_affine
        n = self._k_nominal.size
        return piecewise_linear(k_affine, self._k_nominal, np.arange(n, dtype=np.float64))

    def index_to_lps(self, index_ijk: np.ndarray) -> np.ndarray:
        """Voxel index coordinates (..., 3) as (i=col, j=row, k=slice) -> LPS mm (..., 3).

        A fractional ``k`` lies between its two real neighbouring slices, in proportion.
        """
        ijk = np.array(index_ijk, dtype=np.float64)
        if self._remap_k:
            n = self._k_nominal.size
            ijk[..., 2] = piecewise_linear(
                ijk[..., 2], np.arange(n, dtype=np.float64), self._k_nominal
            )
        a = self.affine_lps
        return np.asarray(ijk @ a[:3, :3].T + a[:3, 3])

    def lps_to_index(self, points_lps: np.ndarray) -> np.ndarray:
        """LPS mm (..., 3) -> continuous voxel index coordinates (i, j, k) (..., 3), exact for
        any slice spacing (k interpolates between the two real neighbouring slices)."""
        pts = np.asarray(points_lps, dtype=np.float64)
        idx = np.asarray(pts @ self._inv_lin.T + self._inv_off)
        if self._remap_k:
            idx[..., 2] = self._k_exact(idx[..., 2])
        return idx

    # ------------------------------------------------------------------ sampling
    def _support(
        self, points_lps: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[int, ...]]:
        """Flat corner indices (N, 8), weights (N, 8), in-grid mask (N,), and the batch shape."""
        pts = np.asarray(points_lps, dtype=np.float64)
        if pts.shape[-1:] != (3,):
            raise ImagingInputError(f"points_lps: expected shape (..., 3), got {pts.shape}")
        batch = pts.shape[:-1]
        top = self._top
        with np.errstate(invalid="ignore", over="ignore"):  # non-finite points: outside
            idx = pts.reshape(-1, 3) @ self._inv_lin.T
            idx += self._inv_off
            if self._remap_k:
                idx[:, 2] = self._k_exact(idx[:, 2])
            inside = ((idx >= -_EDGE_TOL_VOX) & (idx <= top + _EDGE_TOL_VOX)).all(axis=1)
        if not inside.all():
            idx[~inside] = 0.0
        np.clip(idx, 0.0, top, out=idx)
        lo = np.minimum(idx.astype(np.intp), self._max_lo)
        frac = idx - lo
        flats = (lo @ self._strides)[:, None] + self._corner_offsets
        fx = np.empty((frac.shape[0], 3, 2))
        fx[:, :, 1] = frac
        fx[:, :, 0] = 1.0 - frac
        weights = fx[:, 0, _BI] * fx[:, 1, _BJ] * fx[:, 2, _BK]
        return flats, weights, inside, batch

    def _sample_trilinear_unpadded(self, points_lps: np.ndarray, outside_hu: float) -> np.ndarray:
        """:meth:`sample` with ``order=1`` on a volume without padding (``map_coordinates``' bits).

        Index coordinates are built directly as (3, N) rows ``(k, j, i)``. In-hull points
        within the edge tolerance need no clipping: order-1 ``mode="nearest"`` repeats the edge
        voxel, as clipping would. Order-1 splines need no prefilter; the stored voxels (int16
        or float32) are interpolated in float64 without a converted copy of the volume.
        """
        pts = np.asarray(points_lps, dtype=np.float64)
        if pts.shape[-1:] != (3,):
            raise ImagingInputError(f"points_lps: expected shape (..., 3), got {pts.shape}")
        batch = pts.shape[:-1]
        top_kji = self._top[::-1]
        with np.errstate(invalid="ignore", over="ignore"):  # non-finite points: outside
            # one product and sum at a time, in the compiled kernels' order (no BLAS: a
            # matrix product may fuse or reorder them), so both read the same coordinates
            flat = pts.reshape(-1, 3)
            x, y, z = flat[:, 0], flat[:, 1], flat[:, 2]
            m, off = self._inv_lin, self._inv_off
            coords_kji = np.empty((3, flat.shape[0]))
            for row, axis in enumerate((2, 1, 0)):
                coords_kji[row] = m[axis, 0] * x + m[axis, 1] * y + m[axis, 2] * z
                coords_kji[row] += off[axis]
            if self._remap_k:
                coords_kji[0] = self._k_exact(coords_kji[0])
            inside = coords_kji[0] >= -_EDGE_TOL_VOX
            for axis in range(3):
                row = coords_kji[axis]
                if axis:
                    inside &= row >= -_EDGE_TOL_VOX
                inside &= row <= top_kji[axis] + _EDGE_TOL_VOX
        outside = ~inside
        any_outside = bool(outside.any())
        if any_outside:
            coords_kji[:, outside] = 0.0
        out = np.empty(coords_kji.shape[1], dtype=np.float64)
        from ctdrill.imaging.sampling.points_kernel import (
            sample_index_points,
            sample_index_points_numpy,
        )

        if not sample_index_points(self.hu, coords_kji, out):
            sample_index_points_numpy(self.hu, coords_kji, out)  # the same bits, no SciPy
        if any_outside:
            out[outside] = outside_hu
        return out.reshape(batch)

    def sample(
        self, points_lps: np.ndarray, *, order: int = 1, outside_hu: float = AIR_HU
    ) -> np.ndarray:
        """Trilinear HU at LPS points (between the two real neighbouring slices).

        Parameters
        ----------
        points_lps : np.ndarray
            (..., 3) LPS mm. Non-finite points count as outside.
        order : int
            Interpolation order: 1 (trilinear) or 0 (nearest voxel).
        outside_hu : float
            Value outside the voxel-centre hull and substituted for padding voxels.

        Returns
        -------
        np.ndarray
            (...) float64 HU; never NaN.
        """
        if order not in (0, 1):
            raise ImagingInputError(f"sample: order must be 0 or 1, got {order}")
        if order == 1 and self.valid is None:
            return self._sample_trilinear_unpadded(points_lps, float(outside_hu))
        flats, weights, inside, batch = self._support(points_lps)
        if order == 0:
            best = np.argmax(weights, axis=1)
            flats = np.take_along_axis(flats, best[:, None], axis=1)
            weights = np.ones(flats.shape, dtype=np.float64)
        vals = self.hu.reshape(-1)[flats]
        if self.valid is not None:
            vals = np.where(self.valid.reshape(-1)[flats], vals, float(outside_hu))
        out = np.einsum("nc,nc->n", weights, vals)
        out[~inside] = float(outside_hu)
        return out.reshape(batch)

    def inside(self, points_lps: np.ndarray) -> np.ndarray:
        """(...) bool: the point is inside the grid and its trilinear support is all valid.

        Corners with zero weight (a point exactly on a voxel plane) do not count.
        """
        flats, weights, inside, batch = self._support(points_lps)
        if self.valid is not None:
            ok = self.valid.reshape(-1)[flats] | (weights == 0.0)
            inside = inside & np.all(ok, axis=1)
        return inside.reshape(batch)


def _unit_normal(affine_lps: np.ndarray) -> np.ndarray:
    """Unit slice normal: row direction x column direction of the affine (IOP normal)."""
    n = np.cross(affine_lps[:3, 0], affine_lps[:3, 1])
    return np.asarray(n / np.linalg.norm(n))
