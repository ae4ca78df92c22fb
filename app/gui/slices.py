"""Planar reslicing of a CT volume, headless: the slice views and the trajectory cross-section.

Every view is a plane in the world frame (LPS, mm) resampled from the volume with trilinear
interpolation (``CTVolume.sample``, air outside), so oblique and sheared series show true
geometry. Image rows run along ``v_lps`` and columns along ``u_lps``; pixel ``(row, col)`` sits at
``origin_lps + col * pixel_mm * u_lps + row * pixel_mm * v_lps``.

Display convention (radiological): patient left on the image right, anterior up on axial views,
superior up on coronal and sagittal views; the cross-section has the drill going down the image.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, Protocol

import numpy as np

from ctdrill.app.gui.sections import cross3
from ctdrill.hu import AIR_HU

ViewName = Literal["axial", "coronal", "sagittal", "trajectory"]

#: The four slice views in the order the window shows them.
VIEWS: tuple[ViewName, ...] = ("axial", "coronal", "sagittal", "trajectory")


class Sampleable(Protocol):
    """What reslicing needs from a volume (``ctdrill.imaging.CTVolume`` provides it)."""

    @property
    def hu(self) -> np.ndarray: ...

    @property
    def affine_lps(self) -> np.ndarray: ...

    def sample(
        self, points_lps: np.ndarray, *, order: int = 1, outside_hu: float = AIR_HU
    ) -> np.ndarray: ...


@dataclass(frozen=True, eq=False)
class SliceImage:
    """One resampled plane.

    Attributes
    ----------
    hu : (H, W) float32 CT numbers, air (``outside_hu``) outside the volume.
    origin_lps : (3,) LPS mm of pixel (row 0, col 0).
    u_lps, v_lps : (3,) unit vectors along increasing column and row index.
    pixel_mm : pixel size, mm (square pixels).
    """

    view: str
    hu: np.ndarray
    origin_lps: np.ndarray
    u_lps: np.ndarray
    v_lps: np.ndarray
    pixel_mm: float

    @property
    def normal_lps(self) -> np.ndarray:
        """(3,) unit normal of the plane (u x v)."""
        return cross3(self.u_lps, self.v_lps)

    @property
    def extent_mm(self) -> tuple[float, float, float, float]:
        """(left, right, bottom, top) in in-plane mm for ``imshow(origin="upper")``."""
        h, w = self.hu.shape
        p = self.pixel_mm
        return (-0.5 * p, (w - 0.5) * p, (h - 0.5) * p, -0.5 * p)

    def to_plane_mm(self, points_lps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Project LPS points into the plane.

        Parameters
        ----------
        points_lps : (..., 3) LPS mm.

        Returns
        -------
        uv_mm : (..., 2) in-plane coordinates, mm from pixel (0, 0) along u and v.
        off_mm : (...) signed distance from the plane along the normal, mm.
        """
        rel = np.asarray(points_lps, dtype=np.float64) - self.origin_lps
        uv = np.stack([rel @ self.u_lps, rel @ self.v_lps], axis=-1)
        return uv, rel @ self.normal_lps

    def to_lps(self, uv_mm: np.ndarray) -> np.ndarray:
        """In-plane mm (..., 2) back to LPS mm (..., 3), on the plane."""
        uv = np.asarray(uv_mm, dtype=np.float64)
        return self.origin_lps + uv[..., :1] * self.u_lps + uv[..., 1:2] * self.v_lps


def volume_corners_lps(affine_lps: np.ndarray, shape_kji: tuple[int, ...]) -> np.ndarray:
    """(8, 3) LPS mm of the volume's corner voxel centres."""
    nk, nj, ni = shape_kji[:3]
    ijk = np.array(
        [[i, j, k, 1.0] for i in (0, ni - 1) for j in (0, nj - 1) for k in (0, nk - 1)],
        dtype=np.float64,
    )
    return (ijk @ np.asarray(affine_lps, dtype=np.float64).T)[:, :3]


def _corners(volume: Sampleable) -> np.ndarray:
    """(8, 3) LPS mm of the corner voxel centres, through the true slice positions when the
    volume knows them (``CTVolume.index_to_lps``)."""
    to_lps = getattr(volume, "index_to_lps", None)
    if to_lps is None:
        return volume_corners_lps(volume.affine_lps, volume.hu.shape)
    nk, nj, ni = volume.hu.shape[:3]
    ijk = np.array(
        [[i, j, k] for i in (0, ni - 1) for j in (0, nj - 1) for k in (0, nk - 1)],
        dtype=np.float64,
    )
    return np.asarray(to_lps(ijk), dtype=np.float64)


def volume_center_lps(volume: Sampleable) -> np.ndarray:
    """(3,) LPS mm of the volume's centre."""
    return _corners(volume).mean(axis=0)


def _unit(vec: np.ndarray) -> np.ndarray:
    n = float(np.linalg.norm(vec))
    if n == 0.0 or not np.isfinite(n):
        raise ValueError("zero-length direction")
    return np.asarray(vec, dtype=np.float64) / n


def view_axes(
    view: ViewName,
    *,
    axis_lps: np.ndarray | None = None,
    roll_deg: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """In-plane unit vectors (u along columns, v along rows) of a view, LPS.

    ``trajectory`` needs ``axis_lps`` (drill direction, pointing into the patient): v runs down
    the drill and u is perpendicular, chosen closest to patient left (or posterior when the drill
    runs left-right), then rolled by ``roll_deg`` about the axis.
    """
    if view == "axial":
        return np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    if view == "coronal":
        return np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, -1.0])
    if view == "sagittal":
        return np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, -1.0])
    if axis_lps is None:
        raise ValueError("the trajectory view needs the drill axis")
    v = _unit(np.asarray(axis_lps, dtype=np.float64))
    ref = np.array([1.0, 0.0, 0.0]) if abs(v[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = _unit(ref - (ref @ v) * v)
    w = np.cross(u, v)
    a = np.deg2rad(roll_deg)
    u = np.cos(a) * u + np.sin(a) * w
    return u, v


def reslice(
    volume: Sampleable,
    view: ViewName,
    center_lps: np.ndarray,
    *,
    axis_lps: np.ndarray | None = None,
    roll_deg: float = 0.0,
    pixel_mm: float | None = None,
    max_pixels: int = 512,
    order: int = 1,
    outside_hu: float = AIR_HU,
    fast: bool = True,
) -> SliceImage:
    """Resample the plane of ``view`` through ``center_lps``, covering the whole volume.

    Parameters
    ----------
    volume : the CT volume.
    view : axial, coronal, sagittal or trajectory (plane containing the drill axis).
    center_lps : (3,) a point of the plane, LPS mm (the target, or the cursor).
    axis_lps : (3,) drill direction, for the trajectory view.
    pixel_mm : pixel size; default the finest voxel spacing, coarsened so neither side exceeds
        ``max_pixels``.
    order, outside_hu : passed to ``volume.sample`` (trilinear; air outside the volume).
    fast : when the pixels fall on voxel centres in the plane (an orthogonal view of an
        axis-aligned series at its own spacing), blend the two neighbouring voxel planes
        directly: the same values as ``volume.sample``, without the per-pixel gather.

    Returns
    -------
    SliceImage with ``hu`` of shape (rows, cols), float32.
    """
    u, v = view_axes(view, axis_lps=axis_lps, roll_deg=roll_deg)
    center = np.asarray(center_lps, dtype=np.float64)
    corners = _corners(volume)
    rel = corners - center
    cu, cv = rel @ u, rel @ v
    u0, u1 = float(cu.min()), float(cu.max())
    v0, v1 = float(cv.min()), float(cv.max())
    if pixel_mm is None:
        spacing = np.linalg.norm(np.asarray(volume.affine_lps)[:3, :3], axis=0)
        pixel_mm = float(spacing.min())
    span = max(u1 - u0, v1 - v0, 1e-6)
    pixel_mm = max(float(pixel_mm), span / max_pixels)
    ncols = int(np.ceil((u1 - u0) / pixel_mm - 1e-9)) + 1
    nrows = int(np.ceil((v1 - v0) / pixel_mm - 1e-9)) + 1
    origin = center + u0 * u + v0 * v
    hu = None
    if fast and order == 1:
        hu = _grid_aligned(volume, origin, u * pixel_mm, v * pixel_mm, (nrows, ncols), outside_hu)
    if hu is None:
        cols = np.arange(ncols, dtype=np.float64) * pixel_mm
        rows = np.arange(nrows, dtype=np.float64) * pixel_mm
        pts = origin + rows[:, None, None] * v + cols[None, :, None] * u
        hu = volume.sample(pts, order=order, outside_hu=outside_hu).astype(np.float32)
    return SliceImage(
        view=view, hu=hu, origin_lps=origin, u_lps=u, v_lps=v, pixel_mm=float(pixel_mm)
    )


def _grid_aligned(
    volume: Sampleable,
    origin_lps: np.ndarray,
    du_lps: np.ndarray,
    dv_lps: np.ndarray,
    shape: tuple[int, int],
    outside_hu: float,
) -> np.ndarray | None:
    """The trilinear plane when its pixels step by exactly one voxel along two index axes and
    start on a voxel centre, else None. Padding (``valid`` False) counts as ``outside_hu``,
    as in ``CTVolume.sample``. An irregular stack (``regular`` False) is never grid-aligned:
    its planes are sampled through the true slice positions."""
    if not getattr(volume, "regular", True):
        return None
    inv = np.linalg.inv(np.asarray(volume.affine_lps, dtype=np.float64))
    o = inv[:3, :3] @ origin_lps + inv[:3, 3]
    du, dv = inv[:3, :3] @ du_lps, inv[:3, :3] @ dv_lps
    au, av = np.flatnonzero(np.abs(du) > 1e-9), np.flatnonzero(np.abs(dv) > 1e-9)
    if len(au) != 1 or len(av) != 1 or au[0] == av[0]:
        return None
    a_u, a_v = int(au[0]), int(av[0])
    if abs(abs(du[a_u]) - 1.0) > 1e-9 or abs(abs(dv[a_v]) - 1.0) > 1e-9:
        return None
    if abs(o[a_u] - round(o[a_u])) > 1e-6 or abs(o[a_v] - round(o[a_v])) > 1e-6:
        return None
    a_w = 3 - a_u - a_v
    sizes = volume.hu.shape[::-1]  # (cols i, rows j, slices k)
    nrows, ncols = shape
    iu = round(o[a_u]) + int(np.sign(du[a_u])) * np.arange(ncols)
    iv = round(o[a_v]) + int(np.sign(dv[a_v])) * np.arange(nrows)
    if iu.min() < 0 or iu.max() > sizes[a_u] - 1 or iv.min() < 0 or iv.max() > sizes[a_v] - 1:
        return None
    w = float(o[a_w])
    n_w = sizes[a_w]
    if not -1e-6 <= w <= n_w - 1 + 1e-6:
        return np.full(shape, outside_hu, dtype=np.float32)
    w = min(max(w, 0.0), n_w - 1.0)
    k0 = min(int(np.floor(w)), max(n_w - 2, 0))
    frac = w - k0
    valid = getattr(volume, "valid", None)

    def plane(k: int) -> np.ndarray:
        index: list[np.ndarray] = [np.empty(0, dtype=np.intp)] * 3
        index[2 - a_w] = np.array(k, dtype=np.intp)
        index[2 - a_v], index[2 - a_u] = iv[:, None], iu[None, :]
        where = tuple(index)
        vals = np.asarray(volume.hu[where], dtype=np.float64)
        if valid is not None:
            vals = np.where(valid[where], vals, float(outside_hu))
        return vals

    out = plane(k0)
    if frac > 0.0:
        out = (1.0 - frac) * out + frac * plane(k0 + 1)
    return out.astype(np.float32)


def window_to_uint8(hu: np.ndarray, *, level_hu: float, width_hu: float) -> np.ndarray:
    """Map CT numbers to grey levels 0..255 with a linear window (level +- width/2), clipped."""
    if width_hu <= 0:
        raise ValueError("window width must be positive")
    lo = level_hu - width_hu / 2.0
    grey = (np.asarray(hu, dtype=np.float32) - np.float32(lo)) * np.float32(255.0 / width_hu)
    return np.clip(np.rint(grey), 0, 255).astype(np.uint8)


def polyline_in_plane(
    image: SliceImage, points_lps: np.ndarray, *, slab_mm: float
) -> tuple[np.ndarray, np.ndarray]:
    """Project a polyline and flag the vertices within ``slab_mm`` of the plane.

    Returns
    -------
    uv_mm : (N, 2) in-plane coordinates, mm.
    near : (N,) bool, True where ``|distance to plane| <= slab_mm``.
    """
    uv, off = image.to_plane_mm(np.atleast_2d(points_lps))
    return uv, np.abs(off) <= slab_mm
