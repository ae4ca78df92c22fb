"""Where the 3D view's camera starts, and the orientation marker, as pure functions of the anatomy
and the trajectory (the window, the screenshot and the off-screen report use the same rule).

The rule: the drill's target is the focal point; the camera looks at it from the buccal side of
the entry (horizontally away from the anatomy's centre, through the entry: for a jaw, from
outside the arch), perpendicular to the drill axis so the drill runs across the screen, tilted
:data:`TILT_DEG` from above; it stands outside the anatomy's bounding box, far enough that every
corner of the box is inside the view cone (the whole jaw in view).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

#: Tilt of the view direction above the horizontal plane, degrees.
TILT_DEG = 20.0
#: VTK's default vertical view angle, degrees (the horizontal one is wider on a landscape view).
VIEW_ANGLE_DEG = 30.0
#: An entry nearer the anatomy's centre than this fraction of its width has no buccal side
#: of its own: the camera looks from anterior.
CENTRE_TOLERANCE = 0.1
#: Gap between the anatomy's bounding box and the camera, mm.
CLEARANCE_MM = 20.0
#: Face letters of the orientation cube: LPS +x is patient left, +y posterior, +z superior.
ORIENTATION_LETTERS = {"XPlus": "L", "XMinus": "R", "YPlus": "P", "YMinus": "A", "ZPlus": "S"}
ORIENTATION_LETTERS["ZMinus"] = "I"
#: Letter colour on the dark background (white) and the cube's colour behind them.
LETTER_COLOUR = (1.0, 1.0, 1.0)
CUBE_COLOUR = (0.22, 0.30, 0.45)

_SUPERIOR = np.array([0.0, 0.0, 1.0])
_ANTERIOR = np.array([0.0, -1.0, 0.0])


@dataclass(frozen=True, eq=False)
class CameraPose:
    """A camera: ``position_lps`` looks at ``focal_lps`` with ``up`` (unit) up, LPS mm."""

    position_lps: np.ndarray
    focal_lps: np.ndarray
    up: np.ndarray

    @property
    def view_dir(self) -> np.ndarray:
        """Unit vector from the focal point to the camera."""
        d = self.position_lps - self.focal_lps
        return np.asarray(d / np.linalg.norm(d))

    @property
    def distance_mm(self) -> float:
        """Distance from the camera to the focal point, mm."""
        return float(np.linalg.norm(self.position_lps - self.focal_lps))

    def as_pyvista(self) -> list[tuple[float, float, float]]:
        """``[position, focal point, view up]`` for ``plotter.camera_position``."""
        return [_tuple3(self.position_lps), _tuple3(self.focal_lps), _tuple3(self.up)]


def _tuple3(v: np.ndarray) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


def _corners(bounds: Sequence[float]) -> np.ndarray:
    b = [float(x) for x in bounds]
    return np.array([[x, y, z] for x in b[:2] for y in b[2:4] for z in b[4:6]])


def _horizontal_unit(vec: np.ndarray) -> np.ndarray | None:
    h = np.array([vec[0], vec[1], 0.0])
    n = float(np.linalg.norm(h))
    return None if n < 1e-6 else h / n


def fit_distance_mm(
    focal_lps: np.ndarray,
    view_dir: np.ndarray,
    bounds: Sequence[float],
    *,
    view_angle_deg: float = VIEW_ANGLE_DEG,
    clearance_mm: float = CLEARANCE_MM,
) -> float:
    """Smallest distance from ``focal_lps`` along unit ``view_dir`` at which the camera stands
    ``clearance_mm`` beyond the box ``bounds`` (xmin, xmax, ymin, ymax, zmin, zmax) and sees
    every corner of it within half of ``view_angle_deg`` of the view axis."""
    rel = _corners(bounds) - np.asarray(focal_lps, dtype=np.float64)
    along = rel @ view_dir  # towards the camera
    across = np.linalg.norm(rel - along[:, None] * view_dir, axis=1)
    tan_half = np.tan(np.deg2rad(view_angle_deg) / 2.0)
    return float(max(np.max(along) + clearance_mm, np.max(along + across / tan_half)))


def buccal_direction(arch_lps: np.ndarray, entry_lps: np.ndarray) -> np.ndarray | None:
    """The horizontal unit vector out of the dental arch at the point nearest ``entry_lps``:
    perpendicular to the arch there, on its convex side (away from the centroid of its points,
    which lies on the concave, lingual side of any curved arch or arc of one); None when the
    arch is straight there (no side to tell)."""
    pts = np.asarray(arch_lps, dtype=np.float64)[:, :2]
    e = np.asarray(entry_lps, dtype=np.float64)[:2]
    a, b = pts[:-1], pts[1:]
    seg = b - a
    length2 = np.einsum("ij,ij->i", seg, seg)
    ok = length2 > 0
    if not ok.any():
        return None
    t = np.clip(np.einsum("ij,ij->i", e - a, seg) / np.where(ok, length2, 1.0), 0.0, 1.0)
    near = a + t[:, None] * seg
    dist = np.where(ok, np.linalg.norm(near - e, axis=1), np.inf)
    m = int(np.argmin(dist))
    tangent = seg[m] / np.sqrt(length2[m])
    normal = np.array([-tangent[1], tangent[0]])
    away = near[m] - pts.mean(axis=0)
    span = float(np.max(np.linalg.norm(pts - pts.mean(axis=0), axis=1)))
    side = float(normal @ away)
    if span == 0.0 or abs(side) < 1e-3 * span:
        return None
    normal = normal if side > 0 else -normal
    return np.array([normal[0], normal[1], 0.0])


def initial_camera(
    bounds: Sequence[float],
    entry_lps: np.ndarray | None = None,
    target_lps: np.ndarray | None = None,
    *,
    centre_lps: np.ndarray | None = None,
    outward_lps: np.ndarray | None = None,
    view_angle_deg: float = VIEW_ANGLE_DEG,
) -> CameraPose:
    """The starting camera for the anatomy ``bounds`` and the trajectory entry -> target.

    Parameters
    ----------
    bounds : (xmin, xmax, ymin, ymax, zmin, zmax) of what must be in view (the bone surface, or
        the volume), LPS mm.
    entry_lps, target_lps : the trajectory; None: look at the anatomy's centre from anterior.
    centre_lps : the anatomy's centre the buccal side is away from (default: the centre of
        ``bounds``).
    outward_lps : the buccal direction itself (:func:`buccal_direction` of the dental arch),
        which then replaces the centre rule.

    Returns
    -------
    Focal point the target; view direction horizontal-outward through the entry, made
    perpendicular to the drill axis, then tilted :data:`TILT_DEG` towards superior (so the
    drill leaves the screen plane by at most that angle); distance from
    :func:`fit_distance_mm` (outside the box, the whole box in view).
    """
    box = [float(b) for b in bounds]
    centre = (
        np.asarray(_corners(box).mean(axis=0))
        if centre_lps is None
        else np.asarray(centre_lps, dtype=np.float64)
    )
    tilt = np.deg2rad(TILT_DEG)
    if entry_lps is None or target_lps is None:
        focal = np.asarray(_corners(box).mean(axis=0))
        view = _ANTERIOR * np.cos(tilt) + _SUPERIOR * np.sin(tilt)
    else:
        entry = np.asarray(entry_lps, dtype=np.float64)
        focal = np.asarray(target_lps, dtype=np.float64)
        axis = focal - entry
        axis = axis / np.linalg.norm(axis)
        outward = _horizontal_unit(entry - centre)
        off_centre = float(np.hypot(*(entry - centre)[:2]))
        if outward is None or off_centre < CENTRE_TOLERANCE * min(box[1] - box[0], box[3] - box[2]):
            outward = _ANTERIOR  # the entry at the anatomy's centre: no side to prefer
        if outward_lps is not None:
            outward = _horizontal_unit(np.asarray(outward_lps, dtype=np.float64))
            outward = _ANTERIOR if outward is None else outward
        side = outward - (outward @ axis) * axis  # perpendicular to the drill
        if np.linalg.norm(side) < 1e-6:  # a horizontal drill pointing at the centre
            side = _SUPERIOR - (_SUPERIOR @ axis) * axis
            if np.linalg.norm(side) < 1e-6:
                side = _ANTERIOR
        side = side / np.linalg.norm(side)
        lift = _SUPERIOR - (_SUPERIOR @ side) * side  # superior, perpendicular to the side
        lift_n = float(np.linalg.norm(lift))
        lift = lift / lift_n if lift_n > 1e-6 else np.zeros(3)
        view = side * np.cos(tilt) + lift * np.sin(tilt)  # unit: side and lift orthonormal
    view = view / np.linalg.norm(view)
    up = _SUPERIOR - (_SUPERIOR @ view) * view
    if np.linalg.norm(up) < 1e-6:
        up = -_ANTERIOR
    up = up / np.linalg.norm(up)
    dist = fit_distance_mm(focal, view, box, view_angle_deg=view_angle_deg)
    return CameraPose(position_lps=focal + view * dist, focal_lps=focal, up=up)


def scene_bounds(
    surface_bounds: Sequence[float] | None, points_lps: Sequence[np.ndarray]
) -> tuple[float, ...] | None:
    """The box holding ``surface_bounds`` (or nothing) and every point of ``points_lps``."""
    pts = [np.asarray(p, dtype=np.float64).reshape(-1, 3) for p in points_lps if p is not None]
    if surface_bounds is not None:
        pts.append(_corners(surface_bounds))
    pts = [p for p in pts if len(p)]
    if not pts:
        return None
    allp = np.concatenate(pts)
    lo, hi = allp.min(axis=0), allp.max(axis=0)
    return (lo[0], hi[0], lo[1], hi[1], lo[2], hi[2])


def apply_camera(stage: Any, pose: CameraPose) -> None:
    """Put the camera of ``stage`` (a :class:`~ctdrill.app.gui.stage.Stage`) at ``pose``
    (its view angle at VTK's 30 degrees), drawing no frame."""
    renderer = stage.renderer
    camera = renderer.GetActiveCamera()
    camera.SetViewAngle(VIEW_ANGLE_DEG)
    camera.SetPosition(*_tuple3(pose.position_lps))
    camera.SetFocalPoint(*_tuple3(pose.focal_lps))
    camera.SetViewUp(*_tuple3(pose.up))
    camera.OrthogonalizeViewUp()
    renderer.ResetCameraClippingRange()


def orientation_cube() -> Any:
    """A ``vtkAnnotatedCubeActor`` lettered L/R/A/P/S/I (white on a blue-grey cube)."""
    from vtkmodules.vtkRenderingAnnotation import vtkAnnotatedCubeActor

    cube = vtkAnnotatedCubeActor()
    cube.SetFaceTextScale(0.62)
    for face, letter in ORIENTATION_LETTERS.items():
        getattr(cube, f"Set{face}FaceText")(letter)
        getattr(cube, f"Get{face}FaceProperty")().SetColor(*LETTER_COLOUR)
    cube.GetCubeProperty().SetColor(*CUBE_COLOUR)
    cube.GetTextEdgesProperty().SetColor(*LETTER_COLOUR)
    cube.GetTextEdgesProperty().SetLineWidth(1.5)
    return cube


def add_orientation_marker(stage: Any) -> Any:
    """Show :func:`orientation_cube` in the lower-left corner of ``stage``'s view, turned with
    the scene (a :class:`~ctdrill.app.gui.stage.Stage`)."""
    cube = orientation_cube()
    stage.set_marker(cube)
    return cube
