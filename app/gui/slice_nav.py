"""Paging through a volume, headless: where the axial, coronal and sagittal planes may sit,
the orientation letters of a view, the window/level drag and the cursor readout.

A view's planes are ``{p : p . axis = position_mm}`` with ``axis`` an LPS axis (axial: S,
coronal: P, sagittal: L). When one family of the volume's own voxel planes is parallel to the
view (the slices of an axial series, its columns or rows), paging steps through *their* true
positions (``CTVolume.slice_positions_mm`` for the slices: irregular spacing included). When
none is (a gantry-tilted series seen axially), paging steps by the voxel size along the axis
and says so (:attr:`SliceStack.real` False); either way the plane itself is sampled exactly by
``CTVolume.sample`` (:mod:`ctdrill.app.gui.slices`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ctdrill.app.gui.slices import Sampleable, view_axes

#: The LPS axis each orthogonal view pages along, and the name of its coordinate.
VIEW_AXIS: dict[str, tuple[int, str]] = {
    "axial": (2, "z"),
    "coronal": (1, "y"),
    "sagittal": (0, "x"),
}
#: Two plane families are parallel when their unit normals differ by less than this.
PARALLEL_TOL = 1e-6
#: A position within this distance of a plane is on it, mm (voxel planes, a measurement's ends).
ON_PLANE_MM = 1e-6
#: Window/level change per pixel of a drag, HU.
WL_HU_PER_PX = 4.0
#: Narrowest window, HU.
MIN_WIDTH_HU = 1.0
#: LPS letters of the positive and negative directions of each axis.
_LETTERS = (("L", "R"), ("P", "A"), ("S", "I"))


@dataclass(frozen=True, eq=False)
class SliceStack:
    """The positions one pages through in a view.

    Attributes
    ----------
    view : axial, coronal or sagittal.
    axis : 0, 1 or 2, the LPS axis the planes are perpendicular to.
    positions_mm : (N,) increasing LPS coordinates along ``axis`` of the planes.
    indices : (N,) the volume's index of each plane (slice ``k``, row ``j`` or column ``i``),
        or ``0..N-1`` when the planes are not the volume's own.
    real : True when the planes are the volume's own voxel planes.
    label : "slice", "row", "column", or "step" (not the volume's planes).
    """

    view: str
    axis: int
    positions_mm: np.ndarray
    indices: np.ndarray
    real: bool
    label: str

    @property
    def count(self) -> int:
        """Number of planes."""
        return int(self.positions_mm.size)

    def nearest(self, position_mm: float) -> int:
        """Index into :attr:`positions_mm` of the plane nearest ``position_mm``."""
        return int(np.argmin(np.abs(self.positions_mm - position_mm)))

    def step(self, position_mm: float, steps: int) -> float:
        """The position ``steps`` planes on from ``position_mm`` (negative: back), clamped to
        the first and last plane. From between two planes, one step lands on the next plane
        in that direction."""
        pos = self.positions_mm
        if steps == 0 or pos.size == 0:
            return float(position_mm)
        if steps > 0:
            start = int(np.searchsorted(pos, position_mm + ON_PLANE_MM, side="left"))
            k = start + steps - 1
        else:
            start = int(np.searchsorted(pos, position_mm - ON_PLANE_MM, side="right")) - 1
            k = start + steps + 1
        return float(pos[int(np.clip(k, 0, pos.size - 1))])

    def describe(self, position_mm: float) -> str:
        """Readout of a plane position: ``"z 12.50 mm · slice 3/28"``, or between two."""
        name = VIEW_AXIS[self.view][1]
        head = f"{name} {position_mm:.2f} mm"
        k = self.nearest(position_mm)
        n = self.count
        if abs(self.positions_mm[k] - position_mm) <= ON_PLANE_MM:
            if not self.real:
                return f"{head} · step {k + 1}/{n} (oblique to the slices)"
            return f"{head} · {self.label} {int(self.indices[k]) + 1}/{n}"
        lo = int(np.searchsorted(self.positions_mm, position_mm)) - 1
        if lo < 0 or lo >= n - 1:
            return f"{head} · outside the {self.label}s"
        a, b = int(self.indices[lo]) + 1, int(self.indices[lo + 1]) + 1
        if not self.real:
            return f"{head} · between steps {lo + 1} and {lo + 2} (oblique to the slices)"
        return f"{head} · between {self.label}s {min(a, b)} and {max(a, b)}"


def _unit(vec: np.ndarray) -> np.ndarray:
    return np.asarray(vec / np.linalg.norm(vec), dtype=np.float64)


def slice_stack(volume: Sampleable, view: str) -> SliceStack:
    """The planes of ``view`` (axial, coronal or sagittal) one pages through in ``volume``.

    The volume's slices are used when they are parallel to the view (positions from
    ``slice_positions_mm`` when the volume has them), else its columns or rows; otherwise
    uniform steps of one voxel along the view's axis over the volume's extent.
    """
    axis = VIEW_AXIS[view][0]
    e = np.zeros(3)
    e[axis] = 1.0
    a = np.asarray(volume.affine_lps, dtype=np.float64)
    nk, nj, ni = volume.hu.shape[:3]
    col, row, stack = a[:3, 0], a[:3, 1], a[:3, 2]
    slice_normal = _unit(np.cross(col, row))
    positions = getattr(volume, "slice_positions_mm", None)
    families: list[tuple[np.ndarray, np.ndarray, str]] = []
    if positions is not None and np.size(positions) == nk:
        # slice_positions_mm: along the IOP normal; the plane of slice k holds its origin.
        along = np.asarray(positions, dtype=np.float64) * float(slice_normal @ e)
        families.append((slice_normal, along, "slice"))
    else:
        k = np.arange(nk, dtype=np.float64)
        families.append((slice_normal, (a[:3, 3] + k[:, None] * stack) @ e, "slice"))
    i, j = np.arange(ni, dtype=np.float64), np.arange(nj, dtype=np.float64)
    families.append((_unit(np.cross(row, stack)), (a[:3, 3] + i[:, None] * col) @ e, "column"))
    families.append((_unit(np.cross(col, stack)), (a[:3, 3] + j[:, None] * row) @ e, "row"))
    for normal, along, label in families:
        if abs(abs(float(normal @ e)) - 1.0) < PARALLEL_TOL:
            order = np.argsort(along, kind="stable")
            return SliceStack(
                view=view,
                axis=axis,
                positions_mm=np.asarray(along[order]),
                indices=order.astype(np.intp),
                real=True,
                label=label,
            )
    # No voxel plane is parallel: step one voxel along the axis over the extent.
    step = 1.0 / float(np.max(np.abs(np.linalg.inv(a[:3, :3]) @ e)))
    to_lps = getattr(volume, "index_to_lps", None)
    ijk = np.array(
        [[x, y, z] for x in (0, ni - 1) for y in (0, nj - 1) for z in (0, nk - 1)], dtype=float
    )
    corners = to_lps(ijk) if to_lps is not None else ijk @ a[:3, :3].T + a[:3, 3]
    lo, hi = float(np.min(corners[:, axis])), float(np.max(corners[:, axis]))
    n = int(np.floor((hi - lo) / step + 1e-9)) + 1
    return SliceStack(
        view=view,
        axis=axis,
        positions_mm=lo + step * np.arange(n, dtype=np.float64),
        indices=np.arange(n, dtype=np.intp),
        real=False,
        label="step",
    )


def plane_center(point_lps: np.ndarray, view: str, position_mm: float) -> np.ndarray:
    """``point_lps`` moved along the view's axis onto the plane at ``position_mm``."""
    out = np.array(point_lps, dtype=np.float64).reshape(3)
    out[VIEW_AXIS[view][0]] = position_mm
    return out


def direction_letters(vec_lps: np.ndarray) -> str:
    """The LPS letters of a direction, strongest first, leaving out components under a third
    of the largest (``(1, 0, 0)``: "L"; ``(0, -1, -0.5)``: "AI")."""
    v = np.asarray(vec_lps, dtype=np.float64)
    mags = np.abs(v)
    top = float(mags.max())
    if top == 0.0:
        return ""
    order = np.argsort(-mags, kind="stable")
    return "".join(
        _LETTERS[int(ax)][0 if v[ax] > 0 else 1] for ax in order if mags[ax] >= top / 3.0
    )


def orientation_letters(u_lps: np.ndarray, v_lps: np.ndarray) -> dict[str, str]:
    """Letters at the image's edges: ``right`` (+u), ``left`` (-u), ``bottom`` (+v), ``top``
    (-v)."""
    u, v = np.asarray(u_lps, dtype=np.float64), np.asarray(v_lps, dtype=np.float64)
    return {
        "right": direction_letters(u),
        "left": direction_letters(-u),
        "bottom": direction_letters(v),
        "top": direction_letters(-v),
    }


def view_letters(view: str) -> dict[str, str]:
    """:func:`orientation_letters` of an orthogonal view."""
    u, v = view_axes(view)  # type: ignore[arg-type]
    return orientation_letters(u, v)


def dragged_window(
    level_hu: float, width_hu: float, dx_px: float, dy_px: float
) -> tuple[float, float]:
    """Window/level after a drag of ``(dx_px, dy_px)`` screen pixels (y down): right widens,
    down raises the level, ``WL_HU_PER_PX`` HU per pixel; the width stays >= ``MIN_WIDTH_HU``."""
    width = max(MIN_WIDTH_HU, width_hu + WL_HU_PER_PX * dx_px)
    return level_hu + WL_HU_PER_PX * dy_px, width


def window_text(level_hu: float, width_hu: float) -> str:
    """``"W 2000 L 500"``."""
    return f"W {width_hu:.0f} L {level_hu:.0f}"


def cursor_text(volume: Sampleable, point_lps: np.ndarray) -> str:
    """HU at an LPS point (trilinear, the true slice positions) with its position, or that the
    point lies outside the volume (off the grid or on padding): never a made-up number."""
    p = np.asarray(point_lps, dtype=np.float64).reshape(3)
    where = f"L {p[0]:.1f} P {p[1]:.1f} S {p[2]:.1f} mm"
    inside = getattr(volume, "inside", None)
    ok = bool(inside(p[None, :])[0]) if inside is not None else True
    if not ok:
        return f"outside the volume at {where}"
    hu = float(volume.sample(p[None, :], outside_hu=float("nan"))[0])
    if not np.isfinite(hu):
        return f"outside the volume at {where}"
    return f"HU {hu:.0f} at {where}"
