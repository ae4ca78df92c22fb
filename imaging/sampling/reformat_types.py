"""The reformat value (:class:`Reformat`) and the slab sampler the reformats share.

See :mod:`ctdrill.imaging.sampling.reformat` for the conventions (pixels, slab, outside).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from ctdrill.imaging.errors import ImagingInputError
from ctdrill.imaging.sampling.arch import ArchCurve
from ctdrill.imaging.volume import CTVolume

SlabMode = Literal["mean", "mip"]
ReformatKind = Literal["panorama", "cross_section"]

#: Largest image (pixels) a reformat may have; larger is refused (raise pixel_mm).
MAX_PIXELS = 8_000_000
#: Largest number of points sampled at once (bounded memory whatever the volume).
_CHUNK_POINTS = 262_144


@dataclass(frozen=True, eq=False)
class Reformat:
    """A sampled reformat image and its geometry.

    Attributes
    ----------
    hu : np.ndarray
        (H, W) float64 HU (slab mean or maximum), read-only.
    lps : np.ndarray
        (H, W, 3) float64 LPS mm of each pixel's centre sample (the slab's middle), read-only.
    pixel_mm : float
        Pixel size (mm), rows and columns.
    kind : str
        ``"panorama"`` or ``"cross_section"``.
    slab_mm : float
        Slab thickness (mm).
    slab_mode : str
        ``"mean"`` or ``"mip"``.
    slab_samples : int
        Samples across the slab.
    arch_lps : np.ndarray
        (K, 3) the arch used, LPS mm.
    tangent_window_mm : float
        Arc window of the tangent smoothing (mm).
    outside_hu : float
        Value of samples outside the volume.
    at_arc_mm : float | None
        Cross-section: its arc position on the arch (mm); None for a panorama.
    plane_lps : np.ndarray | None
        Cross-section: (4, 3) origin (centre pixel), column direction, row direction (down)
        and slab normal, LPS; None for a panorama.
    column_letters : tuple[str, str]
        Anatomical side of the image's left and right edges: ``R``/``L`` on a panorama
        (patient right/left), ``B``/``Li`` (buccal/lingual) on a cross-section (the patient
        directions ``R L A P`` on a cross-section of a straight arch, which has no inside).
    notes : tuple[str, ...]
        What the caller should know (a slab folding on a tight curve, ...).
    inside_fraction : float
        Fraction of the pixel centres inside the CT (an image wholly outside is refused).
    """

    hu: np.ndarray
    lps: np.ndarray
    pixel_mm: float
    kind: ReformatKind
    slab_mm: float
    slab_mode: SlabMode
    slab_samples: int
    arch_lps: np.ndarray
    tangent_window_mm: float
    outside_hu: float
    at_arc_mm: float | None = None
    plane_lps: np.ndarray | None = None
    column_letters: tuple[str, str] = ("", "")
    notes: tuple[str, ...] = ()
    inside_fraction: float = 1.0
    _curve: ArchCurve | None = field(default=None, repr=False)

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W) pixels."""
        return (int(self.hu.shape[0]), int(self.hu.shape[1]))

    @property
    def extent_mm(self) -> tuple[float, float]:
        """(width, height) between the outer pixel centres, mm."""
        h, w = self.shape
        return ((w - 1) * self.pixel_mm, (h - 1) * self.pixel_mm)

    def project(self, points_lps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Where LPS points fall on the image, and how far they are from its surface.

        Parameters
        ----------
        points_lps : np.ndarray
            (N, 3) LPS mm.

        Returns
        -------
        uv_mm : np.ndarray
            (N, 2) column and row position in mm from the top-left pixel centre (pixel
            ``(i, j)`` is at ``(j, i) * pixel_mm``); NaN where a panorama point's normal foot
            lies beyond the arch's ends.
        offset_mm : np.ndarray
            (N,) signed distance from the reformat's surface along the slab direction, mm
            (``|offset| <= slab_mm / 2`` is inside the slab).
        """
        pts = np.asarray(points_lps, dtype=np.float64).reshape(-1, 3)
        if self.plane_lps is not None:
            origin, col, row, normal = self.plane_lps
            d = pts - origin
            h, w = self.shape
            u = d @ col + 0.5 * (w - 1) * self.pixel_mm
            v = d @ row + 0.5 * (h - 1) * self.pixel_mm
            return np.stack([u, v], axis=1), np.asarray(d @ normal)
        curve = self._curve if self._curve is not None else self._make_curve()
        s, off = curve.project(pts)
        z_top = float(self.lps[0, 0, 2])
        v = np.where(np.isfinite(s), z_top - pts[:, 2], np.nan)
        return np.stack([s, v], axis=1), off

    def lps_at(self, uv_mm: np.ndarray) -> np.ndarray:
        """The LPS point on the image's surface (offset 0) at image position ``uv_mm``: the
        exact inverse of :meth:`project` on the surface, so ``lps_at((j, i) * pixel_mm)`` is
        ``lps[i, j]`` and any position between pixel centres is the surface point there (a
        panorama's column at arc length ``u`` on the arch polyline, its row at height
        ``z_top - v``; a cross-section's plane point).

        Parameters
        ----------
        uv_mm : np.ndarray
            (..., 2) column and row position in mm from the top-left pixel centre.

        Returns
        -------
        np.ndarray
            (..., 3) LPS mm; NaN where a panorama position lies beyond the arch's ends.
        """
        uv = np.asarray(uv_mm, dtype=np.float64)
        u, v = uv[..., 0], uv[..., 1]
        if self.plane_lps is not None:
            origin, col, row, _normal = self.plane_lps
            h, w = self.shape
            du = u - 0.5 * (w - 1) * self.pixel_mm
            dv = v - 0.5 * (h - 1) * self.pixel_mm
            return np.asarray(origin + du[..., None] * col + dv[..., None] * row)
        curve = self._curve if self._curve is not None else self._make_curve()
        length = curve.length_mm
        on = np.isfinite(u) & (u >= -1e-9) & (u <= length + 1e-9)
        xy = curve.point_xy(np.clip(np.where(on, u, 0.0), 0.0, length))
        z_top = float(self.lps[0, 0, 2])
        out = np.concatenate([xy, (z_top - v)[..., None]], axis=-1)
        out[~on] = np.nan
        return np.asarray(out)

    def directions_lps(self, points_lps: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The image's local directions at LPS points, each (N, 3) unit LPS: along increasing
        columns, along increasing rows (down the image) and along the slab (the offset of
        :meth:`project`). A panorama's column direction is the arch tangent at the point's
        column (NaN beyond the arch's ends), its rows run down -z, its slab along the normal.
        """
        pts = np.asarray(points_lps, dtype=np.float64).reshape(-1, 3)
        if self.plane_lps is not None:
            _origin, col, row, normal = self.plane_lps
            ones = np.ones((len(pts), 1))
            return ones * col, ones * row, ones * normal
        curve = self._curve if self._curve is not None else self._make_curve()
        s, _ = curve.project(pts)
        _o, tangent, normal = curve.frame(np.where(np.isfinite(s), s, 0.0))
        tangent[~np.isfinite(s)] = np.nan
        normal[~np.isfinite(s)] = np.nan
        down = np.zeros_like(tangent)
        down[:, 2] = -1.0
        return tangent, down, normal

    def arch_point_lps(self) -> np.ndarray | None:
        """Cross-section: the arch's own point (its height included) at ``at_arc_mm``, LPS
        (3,), for the arch position marker; None for a panorama."""
        if self.at_arc_mm is None:
            return None
        curve = self._curve if self._curve is not None else self._make_curve()
        s = np.array([self.at_arc_mm])
        xy = curve.point_xy(s)[0]
        return np.array([xy[0], xy[1], float(curve.point_z(s)[0])])

    def _make_curve(self) -> ArchCurve:
        return ArchCurve(self.arch_lps, self.tangent_window_mm)

    def metadata(self) -> dict[str, Any]:
        """JSON-ready description: enough to reproduce the image from the same volume."""
        meta: dict[str, Any] = {
            "kind": self.kind,
            "shape_hw": list(self.shape),
            "pixel_mm": self.pixel_mm,
            "slab_mm": self.slab_mm,
            "slab_mode": self.slab_mode,
            "slab_samples": self.slab_samples,
            "tangent_window_mm": self.tangent_window_mm,
            "outside_hu": self.outside_hu,
            "arch_lps": self.arch_lps.tolist(),
            "column_letters": list(self.column_letters),
            "top_left_lps": self.lps[0, 0].tolist(),
            "notes": list(self.notes),
            "inside_fraction": self.inside_fraction,
        }
        if self.at_arc_mm is not None:
            meta["at_arc_mm"] = self.at_arc_mm
        if self.plane_lps is not None:
            keys = ("centre_lps", "column_dir_lps", "row_dir_lps", "slab_normal_lps")
            meta.update({k: v.tolist() for k, v in zip(keys, self.plane_lps, strict=True)})
        return meta


def readonly(arr: np.ndarray) -> np.ndarray:
    arr.flags.writeable = False
    return arr


def sample_slab(
    volume: CTVolume,
    centres: np.ndarray,
    normals: np.ndarray,
    offsets_mm: np.ndarray,
    mode: SlabMode,
    outside_hu: float,
) -> np.ndarray:
    """Slab mean or maximum at (H, W, 3) centres along (H, W, 3) or (1, W, 3) normals."""
    h, w = centres.shape[:2]
    n = offsets_mm.size
    out = np.empty((h, w), dtype=np.float64)
    rows = max(1, _CHUNK_POINTS // max(1, w * n))
    for r0 in range(0, h, rows):
        c = centres[r0 : r0 + rows]
        nrm = normals if normals.shape[0] == 1 else normals[r0 : r0 + rows]
        pts = c[:, :, None, :] + offsets_mm[None, None, :, None] * nrm[:, :, None, :]
        vals = volume.sample(pts, order=1, outside_hu=outside_hu)
        out[r0 : r0 + rows] = vals.mean(axis=2) if mode == "mean" else vals.max(axis=2)
    return out


def count_check(h: int, w: int, pixel_mm: float) -> None:
    if h * w > MAX_PIXELS:
        raise ImagingInputError(
            f"reformat: {h} x {w} pixels at {pixel_mm:g} mm exceeds {MAX_PIXELS} pixels; "
            "use a larger pixel size or a smaller height/width"
        )
