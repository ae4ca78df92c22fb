"""Meshes of the plan's objects in LPS mm, as pure functions (no plotter): the drill, a landmark's
tube and its margin envelope, and an implant body as a solid of revolution of its profile."""

from __future__ import annotations

import threading
from collections import OrderedDict
from functools import lru_cache
from typing import Protocol

import numpy as np
import pyvista as pv


class DrawnLandmark(Protocol):
    """What :func:`landmark_meshes` reads of a landmark
    (:class:`ctdrill.app.gui.scene.LandmarkGeometry` is one)."""

    @property
    def points_lps(self) -> np.ndarray: ...

    @property
    def radius_mm(self) -> float: ...

    @property
    def margin_mm(self) -> float: ...

    @property
    def cloud(self) -> bool: ...


def drill_mesh(
    entry_lps: np.ndarray,
    target_lps: np.ndarray,
    *,
    diameter_mm: float,
    tip_length_mm: float,
    shank_mm: float = 20.0,
    resolution: int = 32,
) -> pv.PolyData:
    """The drill with its tip point at the entry (depth 0): a cone of length ``tip_length_mm``
    behind which a cylinder of ``diameter_mm`` runs back ``shank_mm`` out of the patient.

    Translate it by ``depth_mm * axis`` to put the tip at depth ``depth_mm``.
    """
    entry = np.asarray(entry_lps, dtype=np.float64)
    axis = unit(np.asarray(target_lps, dtype=np.float64) - entry)
    radius = diameter_mm / 2.0
    tip_len = max(tip_length_mm, 1e-3)
    cone = pv.Cone(
        center=entry - axis * tip_len / 2.0,
        direction=axis,
        height=tip_len,
        radius=radius,
        resolution=resolution,
        capping=True,
    )
    cyl = pv.Cylinder(
        center=entry - axis * (tip_len + shank_mm / 2.0),
        direction=axis,
        radius=radius,
        height=shank_mm,
        resolution=resolution,
        capping=True,
    )
    out: pv.PolyData = (cone + cyl).extract_surface(algorithm=None)
    return out


#: Landmark meshes each thread keeps (the latest made or used last): the 3D view makes a canal
#: click's tubes while the click's path is planned (:meth:`ctdrill.app.gui.view3d.View3D.
#: prefetch`) and draws them with the path result; an undo finds the previous ones.
LANDMARK_MESHES_KEPT = 8
_kept = threading.local()


def landmark_meshes(landmark: DrawnLandmark) -> tuple[pv.PolyData, pv.PolyData | None]:
    """(body, margin envelope): the canal tube (or point sphere) and the tube grown by the
    margin; a surface cloud (a mask landmark's) is drawn as points, without an envelope.

    The meshes of the last :data:`LANDMARK_MESHES_KEPT` geometries are kept per thread and
    returned again (the same objects: read them, never change them)."""
    pts = np.atleast_2d(np.asarray(landmark.points_lps, dtype=np.float64))
    key: tuple[object, ...] = (pts.shape, pts.tobytes(), float(landmark.radius_mm))
    key += (float(landmark.margin_mm), bool(landmark.cloud))
    kept: OrderedDict[tuple[object, ...], tuple[pv.PolyData, pv.PolyData | None]] | None
    kept = getattr(_kept, "meshes", None)
    if kept is None:
        kept = _kept.meshes = OrderedDict()
    hit = kept.get(key)
    if hit is not None:
        kept.move_to_end(key)
        return hit
    made = _landmark_meshes(pts, landmark)
    kept[key] = made
    while len(kept) > LANDMARK_MESHES_KEPT:
        kept.popitem(last=False)
    return made


def _landmark_meshes(
    pts: np.ndarray, landmark: DrawnLandmark
) -> tuple[pv.PolyData, pv.PolyData | None]:
    outer = landmark.radius_mm + landmark.margin_mm
    if landmark.cloud:
        return pv.PolyData(pts), None
    if len(pts) == 1:
        body = sphere_mesh(max(landmark.radius_mm, 0.3), pts[0])
        env = sphere_mesh(max(outer, 0.3), pts[0])
        return body, env
    line = pv.lines_from_points(pts)
    body = line.tube(radius=max(landmark.radius_mm, 0.2), n_sides=24, capping=True)
    env = line.tube(radius=max(outer, 0.2), n_sides=24, capping=True)
    return body, env


#: Segments of a sphere around and from pole to pole (pyvista's ``Sphere`` default).
SPHERE_RESOLUTION = 30


@lru_cache(maxsize=4)
def _unit_sphere(resolution: int) -> pv.PolyData:
    return pv.Sphere(
        radius=1.0, center=(0.0, 0.0, 0.0), theta_resolution=resolution, phi_resolution=resolution
    )


def sphere_mesh(
    radius_mm: float, center_lps: np.ndarray, *, resolution: int = SPHERE_RESOLUTION
) -> pv.PolyData:
    """``pv.Sphere(radius=radius_mm, center=center_lps)``'s mesh (the same points, to rounding,
    faces and normals), made from one cached unit sphere scaled and moved: 0.1 ms instead of
    pyvista's 7 ms of source, rotation and translation filters for every sphere the 3D view
    rebuilds (the stop mark moves with every new path)."""
    out = _unit_sphere(int(resolution)).copy(deep=True)
    out.points = out.points * float(radius_mm) + np.asarray(center_lps, dtype=np.float64)
    return out


def unit(vec: np.ndarray) -> np.ndarray:
    n = float(np.linalg.norm(vec))
    if n == 0.0:
        raise ValueError("entry and target coincide: the trajectory has no direction")
    return np.asarray(vec, dtype=np.float64) / n


def _perpendicular_basis(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing unit ``axis`` to a right-handed orthonormal frame."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(axis, helper)
    u /= np.linalg.norm(u)
    return u, np.cross(axis, u)


def revolution_mesh(
    base_lps: np.ndarray,
    axis_lps: np.ndarray,
    s_mm: np.ndarray,
    r_mm: np.ndarray,
    *,
    resolution: int = 40,
) -> pv.PolyData:
    """The closed solid of revolution of the profile (``s_mm``, ``r_mm``) about the line from
    ``base_lps`` along unit ``axis_lps``: the ring at ``s_mm[m]`` along the axis has radius
    ``r_mm[m]``; an end with a non-zero radius is closed by a flat disc.

    Parameters
    ----------
    base_lps : (3,) the profile's s = 0 on the axis, LPS mm.
    axis_lps : (3,) direction of increasing s (normalised here).
    s_mm, r_mm : (M,) the profile, M >= 2, s non-decreasing, r >= 0.
    resolution : points per ring.
    """
    s = np.asarray(s_mm, dtype=np.float64).reshape(-1)
    r = np.asarray(r_mm, dtype=np.float64).reshape(-1)
    if s.size < 2 or s.size != r.size or np.any(r < 0) or np.any(np.diff(s) < 0):
        raise ValueError("profile: s_mm and r_mm need the same length >= 2, s ascending, r >= 0")
    axis = unit(np.asarray(axis_lps, dtype=np.float64))
    u, v = _perpendicular_basis(axis)
    base = np.asarray(base_lps, dtype=np.float64)
    theta = np.linspace(0.0, 2.0 * np.pi, resolution, endpoint=False)
    ring = np.cos(theta)[:, None] * u + np.sin(theta)[:, None] * v  # (T, 3)
    m, t = s.size, resolution
    pts = base + s[:, None, None] * axis + r[:, None, None] * ring[None, :, :]  # (M, T, 3)
    points = pts.reshape(-1, 3)
    ids = np.arange(m * t).reshape(m, t)
    nxt = np.roll(ids, -1, axis=1)
    quads = np.stack([ids[:-1], nxt[:-1], nxt[1:], ids[1:]], axis=-1).reshape(-1, 4)
    faces = [np.hstack([np.full((len(quads), 1), 4), quads]).ravel()]
    extra: list[np.ndarray] = []
    for end, idx in ((0, ids[0]), (m - 1, ids[-1])):
        if r[end] > 0.0:
            centre = len(points) + len(extra)
            extra.append(base + s[end] * axis)
            order = idx if end == m - 1 else idx[::-1]
            tri = np.stack([np.full(t, centre), order, np.roll(order, -1)], axis=1)
            faces.append(np.hstack([np.full((t, 1), 3), tri]).ravel())
    if extra:
        points = np.vstack([points, np.array(extra)])
    mesh = pv.PolyData(points, np.concatenate(faces))
    return mesh.triangulate().clean(tolerance=1e-9)


def implant_mesh(
    platform_lps: np.ndarray,
    axis_lps: np.ndarray,
    s_mm: np.ndarray,
    r_mm: np.ndarray,
    *,
    resolution: int = 40,
) -> pv.PolyData:
    """An implant body: the solid of revolution of ``ImplantSpec.profile_mm()`` (s from the
    platform (0) to the apex, radius r) with its platform at ``platform_lps`` and the apex along
    unit ``axis_lps`` (entry -> target), LPS mm."""
    return revolution_mesh(platform_lps, axis_lps, s_mm, r_mm, resolution=resolution)
