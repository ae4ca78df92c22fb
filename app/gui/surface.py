"""The bone iso-surface of a CT volume, from every slice at full in-plane resolution.

A flying-edges contour (``vtkFlyingEdges3D``, multithreaded through VTK's SMP tools) in *index*
space on the volume padded with air (so the surface closes at the volume's border), mapped to
LPS mm point by point with the volume's own index -> LPS map (``CTVolume.index_to_lps``: exact
for irregular slice positions, oblique and sheared (gantry-tilt) stacks). The normals come from
the contour's voxel gradient and are carried through the same map (the inverse transpose of its
Jacobian), so no separate normals pass is needed and shading stays smooth.

It runs in a worker thread (:mod:`ctdrill.app.gui.compute`) and returns the triangles in
slab-wise pieces (:func:`surface_piece`) that the 3D view hands to VTK one per event-loop pass,
so no single pass uploads millions of triangles (see :mod:`ctdrill.app.gui.view3d`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pyvista as pv
from vtkmodules.util.numpy_support import numpy_to_vtk
from vtkmodules.vtkCommonCore import vtkSMPTools
from vtkmodules.vtkFiltersCore import vtkFlyingEdges3D

from ctdrill.hu import AIR_HU
from ctdrill.imaging.display import BONE_SURFACE_HU

#: Triangles per piece the 3D view adds in one event-loop pass (see ``surface_piece``).
PIECE_TRIANGLES = 30_000
#: Most triangles of the surface the 3D view draws. On the software OpenGL of these machines
#: (Mesa llvmpipe under Xvfb, 2 shared cores) a frame costs roughly 0.1-0.3 ms per thousand
#: triangles of translucent bone, so this keeps one frame of the whole surface near the 100 ms
#: the UI thread may be held (bench/bench_gui3d.py measures it). Above it the voxels are
#: averaged in blocks (``display_block``), slices kept whole where they are thick.
DISPLAY_TRIANGLES = 300_000
#: Most triangles the 3D view ever asks for (a fast GPU: every voxel of most series).
MAX_TRIANGLES = 4_000_000

_SMP_READY = False


def _use_threads() -> None:
    """Run VTK's SMP filters on threads (the wheels default to the sequential backend)."""
    global _SMP_READY
    if not _SMP_READY:
        vtkSMPTools.SetBackend("STDThread")
        _SMP_READY = True


def contour_grid(values: np.ndarray, iso: float, *, normals: bool = True) -> pv.PolyData:
    """Flying-edges triangles of ``values`` (k, j, i) at ``iso``, in index space (x = i)."""
    _use_threads()
    arr = np.ascontiguousarray(values)
    nk, nj, ni = arr.shape
    grid = pv.ImageData(dimensions=(ni, nj, nk))
    grid.point_data.set_array(numpy_to_vtk(arr.ravel(), deep=False), "v")
    grid.point_data.active_scalars_name = "v"
    fe = vtkFlyingEdges3D()
    fe.SetInputData(grid)
    fe.SetValue(0, float(iso))
    fe.SetComputeNormals(normals)
    fe.SetComputeGradients(False)
    fe.SetComputeScalars(False)
    fe.Update()
    return pv.wrap(fe.GetOutput())


def block_grid(
    hu: np.ndarray,
    *,
    block: tuple[int, int, int] = (1, 1, 1),
    stride: int = 1,
    valid: np.ndarray | None = None,
    outside_hu: float = AIR_HU,
) -> np.ndarray:
    """The grid the surface is contoured on, with one layer of ``outside_hu`` around it (so
    the surface closes at the volume's border).

    ``block`` (fi, fj, fk): each sample is the mean of fk x fj x fi voxels (every voxel counts;
    the volume is padded with ``outside_hu`` to whole blocks); sample b sits at index
    ``b * f + (f - 1) / 2``. ``stride`` > 1 instead keeps every stride-th voxel (the earlier
    coarse surface). (1, 1, 1) and stride 1: the voxels themselves, in their own dtype.
    """
    fi, fj, fk = (int(f) for f in block)
    sub = hu[::stride, ::stride, ::stride] if stride > 1 else hu
    vsub = None
    if valid is not None:
        vsub = valid[::stride, ::stride, ::stride] if stride > 1 else valid
        vsub = np.asarray(vsub, dtype=bool)
        if vsub.all():
            vsub = None
    if (fi, fj, fk) == (1, 1, 1):
        dtype = sub.dtype if sub.dtype in (np.int16, np.float32) else np.dtype(np.float32)
        fill = np.asarray(outside_hu).astype(dtype)
        padded = np.full(tuple(n + 2 for n in sub.shape), fill, dtype=dtype)
        inner = padded[1:-1, 1:-1, 1:-1]
        inner[...] = sub
        if vsub is not None:
            inner[~vsub] = fill
        return padded
    if vsub is not None:
        sub = np.where(vsub, sub, np.asarray(outside_hu).astype(sub.dtype))
    nk, nj, ni = sub.shape
    shape_b = (-(-nk // fk), -(-nj // fj), -(-ni // fi))
    # Block sums slab by slab: a slab's slices added into one float plane (padded to whole
    # blocks with zeros), then the plane's strided views within a block added (every voxel
    # read once, in cache: 5x faster than strided views of the whole volume, and the same
    # sums for integer HU); voxels beyond the volume count as outside (below).
    total = np.zeros(shape_b, dtype=np.float32)
    plane = np.zeros((shape_b[1] * fj, shape_b[2] * fi), dtype=np.float32)
    blocks = plane.reshape(shape_b[1], fj, shape_b[2], fi)
    for b in range(shape_b[0]):
        plane[:nj, :ni] = sub[b * fk]
        for k in range(b * fk + 1, min((b + 1) * fk, nk)):
            plane[:nj, :ni] += sub[k]
        out = total[b]
        for dj in range(fj):
            for di in range(fi):
                out += blocks[:, dj, :, di]
    present = [
        np.minimum(f, n - f * np.arange(nb)).astype(np.float32)
        for f, n, nb in ((fk, nk, shape_b[0]), (fj, nj, shape_b[1]), (fi, ni, shape_b[2]))
    ]
    inside = present[0][:, None, None] * present[1][None, :, None] * present[2][None, None, :]
    size = float(fi * fj * fk)
    total += (size - inside) * np.float32(outside_hu)
    total /= np.float32(size)
    padded = np.full(tuple(n + 2 for n in shape_b), outside_hu, dtype=np.float32)
    padded[1:-1, 1:-1, 1:-1] = total
    return padded


def block_for(
    spacing_mm: tuple[float, float, float], size_mm: float, *, merge_slices: bool = True
) -> tuple[int, int, int]:
    """Voxels per block along (i, j, k) for blocks no larger than ``size_mm`` along any axis
    (at least 1); with ``merge_slices`` False (an irregular stack) slices are never merged."""
    f = [max(1, int(np.floor(size_mm / float(sp) + 1e-9))) for sp in spacing_mm]
    if not merge_slices:
        f[2] = 1
    return (f[0], f[1], f[2])


def display_block(
    hu: np.ndarray,
    spacing_mm: tuple[float, float, float],
    *,
    iso_hu: float = BONE_SURFACE_HU,
    valid: np.ndarray | None = None,
    outside_hu: float = AIR_HU,
    merge_slices: bool = True,
    max_triangles: int = DISPLAY_TRIANGLES,
    max_tries: int = 6,
) -> tuple[int, int, int]:
    """The finest block (:func:`block_for`) whose surface has at most ``max_triangles``
    triangles, found by counting: a first count at blocks of 4 pixels predicts the size for
    the budget (triangles scale with the inverse block area, or length where slices stay
    whole), then each candidate is counted, finer while it fits, coarser while it does not.
    Every voxel when that fits. Slices are merged only with ``merge_slices`` (a regular stack)
    and only where thinner than the block; after ``max_tries`` counts the coarsest fitting
    block found (or the last counted) is returned."""
    pixel = float(min(spacing_mm[0], spacing_mm[1]))
    counts: dict[tuple[int, int, int], int] = {}

    def count(block: tuple[int, int, int]) -> int:
        if block not in counts:
            grid = block_grid(hu, block=block, valid=valid, outside_hu=outside_hu)
            counts[block] = contour_grid(grid, iso_hu, normals=False).n_cells
        return counts[block]

    # Bracket the in-plane factor f (blocks of f pixels): f_fit fits, f_over does not.
    f_over, f_fit = 0, 0
    f = 4
    for _ in range(max_tries):
        block = block_for(spacing_mm, f * pixel, merge_slices=merge_slices)
        n_tri = count(block)
        if n_tri <= max_triangles:
            f_fit = f
        else:
            f_over = f
        if f_fit == 1 or (f_fit and f_fit - f_over <= 1):
            break
        power = 2.0 if block[2] > 1 else 1.5
        guess = round(f * (max(n_tri, 1) / max_triangles) ** (1.0 / power))
        hi = f_fit - 1 if f_fit else 10**6
        f = min(max(guess, f_over + 1), hi)
        if f == f_fit:
            break
    best = block_for(spacing_mm, (f_fit or f) * pixel, merge_slices=merge_slices)
    return best


def bone_surface(
    hu: np.ndarray,
    affine_lps: np.ndarray,
    *,
    iso_hu: float = BONE_SURFACE_HU,
    max_dim: int | None = None,
    valid: np.ndarray | None = None,
    outside_hu: float = AIR_HU,
    index_to_lps: Callable[[np.ndarray], np.ndarray] | None = None,
    block: tuple[int, int, int] = (1, 1, 1),
    piece_triangles: int = PIECE_TRIANGLES,
) -> pv.PolyData:
    """Iso-surface of the CT at ``iso_hu``, LPS mm, from every voxel.

    Parameters
    ----------
    hu : (slices, rows, cols) CT numbers (contoured in their own dtype: no float copy).
    affine_lps : (4, 4) index (i=col, j=row, k=slice) to LPS mm.
    iso_hu : contour level.
    max_dim : None (default): every voxel. An int strides the volume so that no axis has more
        than this many samples (the coarse surface of earlier versions, kept as the benchmark's
        peer: on 512 x 512 series it keeps every 4th slice).
    valid : optional (slices, rows, cols) mask; padding (False) counts as ``outside_hu``.
    index_to_lps : maps (N, 3) index coordinates to LPS mm (``CTVolume.index_to_lps``: exact
        for irregular slice positions); default the affine.
    block : (fi, fj, fk) voxels averaged into one sample before contouring (see
        :func:`block_grid`; (1, 1, 1): every voxel itself). With fk = 1 every slice keeps its
        own layer of the surface.
    piece_triangles : the triangles come in pieces of at most this many, each with its own
        block of points (:func:`surface_piece`), so a viewer can upload them one at a time.

    Returns
    -------
    Triangle surface with unit point normals (``Normals``, pointing out of the bone) in LPS;
    field data ``block`` says which block it was contoured at. Empty when nothing crosses
    ``iso_hu``.
    """
    stride = 1
    if max_dim is not None:
        stride = max(1, int(np.ceil(max(hu.shape[:3]) / max_dim)))
        block = (1, 1, 1)
    grid = block_grid(hu, block=block, stride=stride, valid=valid, outside_hu=outside_hu)
    surf = contour_grid(grid, iso_hu)
    del grid
    if surf.n_points == 0:
        return pv.PolyData()
    f = np.asarray(block, dtype=np.float64) * stride
    offset = (np.asarray(block, dtype=np.float64) - 1.0) / 2.0  # a block's centre
    aff = np.asarray(affine_lps, dtype=np.float64)
    to_lps = (
        index_to_lps if index_to_lps is not None else (lambda p: p @ aff[:3, :3].T + aff[:3, 3])
    )

    def grid_to_lps(g: np.ndarray) -> np.ndarray:  # padded-grid coordinates -> LPS
        return np.asarray(to_lps((g - 1.0) * f + offset))

    g = np.asarray(surf.points, dtype=np.float64)
    points = grid_to_lps(g)
    normals = _carry_normals(g, np.asarray(surf.point_data["Normals"], np.float64), grid_to_lps)
    out = _in_pieces(points, normals, np.asarray(surf.regular_faces), piece_triangles)
    out.field_data["block"] = np.asarray(block, dtype=np.int64)
    return out


def _carry_normals(
    ijk: np.ndarray, n_ijk: np.ndarray, to_lps: Callable[[np.ndarray], np.ndarray]
) -> np.ndarray:
    """Normals (N, 3) at index points ``ijk`` carried to LPS by the map's inverse-transpose
    Jacobian (columns by central differences of half a voxel), unit length."""
    cols = []
    for axis in range(3):
        step = np.zeros(3)
        step[axis] = 0.5
        cols.append(np.asarray(to_lps(ijk + step)) - np.asarray(to_lps(ijk - step)))
    c0, c1, c2 = cols
    # J^-T n = (n0 (c1 x c2) + n1 (c2 x c0) + n2 (c0 x c1)) / det J
    det = np.einsum("ij,ij->i", c0, np.cross(c1, c2))
    out = (
        n_ijk[:, :1] * np.cross(c1, c2)
        + n_ijk[:, 1:2] * np.cross(c2, c0)
        + n_ijk[:, 2:3] * np.cross(c0, c1)
    ) * np.sign(det)[:, None]
    norm = np.linalg.norm(out, axis=1)
    norm[norm == 0.0] = 1.0
    return np.asarray(out / norm[:, None])


def _in_pieces(
    points: np.ndarray, normals: np.ndarray, tris: np.ndarray, max_triangles: int
) -> pv.PolyData:
    """The surface with its triangles cut into runs of at most ``max_triangles`` (the contour
    emits them slice by slice, so a run is a slab) and its points re-ordered so each run uses
    only its own contiguous block of points (points on a seam are repeated, once per run).
    Field data ``piece_points`` and ``piece_triangles`` hold the blocks' offsets."""
    n_tri = len(tris)
    starts = list(range(0, n_tri, max_triangles)) or [0]
    if len(starts) == 1:
        blocks_p, blocks_n, blocks_t = [points], [normals], [tris]
    else:
        blocks_p, blocks_n, blocks_t = [], [], []
        offset = 0
        for start in starts:
            part = tris[start : start + max_triangles]
            mask = np.zeros(len(points), dtype=bool)
            mask[part.ravel()] = True
            used = np.flatnonzero(mask)
            local = (np.cumsum(mask) - 1)[part]
            blocks_p.append(points[used])
            blocks_n.append(normals[used])
            blocks_t.append(local + offset)
            offset += len(used)
    out = pv.PolyData.from_regular_faces(np.concatenate(blocks_p), np.concatenate(blocks_t))
    out.point_data["Normals"] = np.concatenate(blocks_n)
    out.point_data.active_normals_name = "Normals"
    out.field_data["piece_points"] = np.cumsum([0] + [len(b) for b in blocks_p])
    out.field_data["piece_triangles"] = np.cumsum([0] + [len(b) for b in blocks_t])
    return out


def piece_count(surface: pv.PolyData) -> int:
    """Number of pieces of a :func:`bone_surface` (1 for any other non-empty mesh, 0 when
    empty)."""
    if surface.n_points == 0:
        return 0
    if "piece_triangles" not in surface.field_data:
        return 1
    return len(surface.field_data["piece_triangles"]) - 1


def surface_piece(surface: pv.PolyData, index: int) -> pv.PolyData:
    """Piece ``index`` of a :func:`bone_surface`: its points and normals are views of the
    surface's (no copy), its triangles re-numbered from 0. A mesh without pieces is piece 0."""
    if "piece_triangles" not in surface.field_data:
        if index != 0:
            raise IndexError(f"piece {index}: the mesh is one piece")
        return surface
    p0, p1 = (int(x) for x in surface.field_data["piece_points"][index : index + 2])
    t0, t1 = (int(x) for x in surface.field_data["piece_triangles"][index : index + 2])
    tris = np.asarray(surface.regular_faces[t0:t1]) - p0
    piece = pv.PolyData.from_regular_faces(np.asarray(surface.points)[p0:p1], tris)
    piece.point_data["Normals"] = np.asarray(surface.point_data["Normals"])[p0:p1]
    piece.point_data.active_normals_name = "Normals"
    return piece
