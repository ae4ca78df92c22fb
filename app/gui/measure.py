"""Distance and angle measurements, headless: the numbers the measuring tools draw.

Points are LPS mm, placed by clicks on a view's surface (a slice plane, the cross-section, or
the panoramic's curved curtain), so lengths and angles are those in the patient, whatever
the view: on a panorama a horizontal stretch of image is arc length along the arch, while the
measured distance is the straight line between the two points in the patient.
"""

from __future__ import annotations

import math

import numpy as np

#: Clicks a measurement takes: two ends of a distance; arm, vertex, arm of an angle.
CLICKS = {"distance": 2, "angle": 3}


def distance_mm(a_lps: np.ndarray, b_lps: np.ndarray) -> float:
    """Straight-line distance between two LPS points, mm."""
    return float(np.linalg.norm(np.asarray(b_lps, float) - np.asarray(a_lps, float)))


def angle_deg(a_lps: np.ndarray, vertex_lps: np.ndarray, b_lps: np.ndarray) -> float:
    """Angle at ``vertex_lps`` between the arms to ``a_lps`` and ``b_lps``, degrees (0-180);
    NaN when an arm has no length."""
    v = np.asarray(vertex_lps, dtype=np.float64)
    p = np.asarray(a_lps, dtype=np.float64) - v
    q = np.asarray(b_lps, dtype=np.float64) - v
    n = float(np.linalg.norm(p) * np.linalg.norm(q))
    if n == 0.0:
        return float("nan")
    # atan2 of |p x q| and p . q: exact near 0 and 180 degrees, where acos loses digits
    return math.degrees(math.atan2(float(np.linalg.norm(np.cross(p, q))), float(p @ q)))


def measure_label(kind: str, points_lps: list[np.ndarray]) -> str | None:
    """The measurement's text once complete (``12.34 mm``, ``87.5°``), None before."""
    if len(points_lps) < CLICKS[kind]:
        return None
    if kind == "distance":
        return f"{distance_mm(points_lps[0], points_lps[1]):.2f} mm"
    return f"{angle_deg(points_lps[0], points_lps[1], points_lps[2]):.1f}°"


def next_points(kind: str, points_lps: list[np.ndarray], click_lps: np.ndarray) -> list[np.ndarray]:
    """The measurement's points after a click: a complete one starts again."""
    done = len(points_lps) >= CLICKS[kind]
    return [click_lps] if done else [*points_lps, click_lps]
