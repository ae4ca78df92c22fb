"""The centreline 3D Slicer draws through a Curve markup's control points.

Slicer's open Curve (``vtkMRMLMarkupsCurveNode``, default curve type ``spline``) is a
``vtkParametricSpline`` of three ``vtkCardinalSpline`` (one per coordinate) with
``ParameterizeByLength`` off and VTK's default end conditions: the control points sit at equal
parameter steps (knots 0, 1, ..., N-1), each coordinate is a C2 cubic spline through them, and
the first derivative is 0 at both ends (``LeftConstraint = RightConstraint = 1``, value 0).
Slicer samples it at ``NumberOfPointsPerInterpolatingSegment = 10`` points per segment,
uniformly in the parameter, and draws and measures the polyline through those samples.

ctdrill's canal centreline for a Slicer Curve is exactly that polyline: :func:`slicer_curve`
returns the ``10 (N - 1) + 1`` samples (a single control point stays a point). The curve type
is not stored in a ``.mrk.json`` (it lives in the scene file), so a curve read from markups is
always this spline, which is what Slicer shows after loading the same file.
"""

from __future__ import annotations

import numpy as np

#: Samples per segment between two control points (Slicer's curve generator default).
POINTS_PER_SEGMENT = 10


def slicer_curve(control_points: np.ndarray) -> np.ndarray:
    """Slicer's sampled spline through ``control_points`` (N, 3): (10 (N-1) + 1, 3) points.

    The first and last samples are the first and last control points; every control point is
    a sample (at index ``10 i``).
    """
    pts = np.asarray(control_points, dtype=np.float64).reshape(-1, 3)
    n = len(pts)
    if n < 2:
        return pts.copy()
    from scipy.interpolate import CubicSpline  # 0.2-0.4 s to import: only Slicer curves

    knots = np.arange(n, dtype=np.float64)
    spline = CubicSpline(knots, pts, axis=0, bc_type=((1, np.zeros(3)), (1, np.zeros(3))))
    total = POINTS_PER_SEGMENT * (n - 1) + 1
    # Slicer evaluates at u = k / (total - 1) in [0, 1]; the spline's knot is u (N - 1).
    u = np.arange(total, dtype=np.float64) / (total - 1)
    out: np.ndarray = spline(u * (n - 1))
    # The control points themselves, exactly (no rounding from the evaluation).
    out[::POINTS_PER_SEGMENT] = pts
    return out
