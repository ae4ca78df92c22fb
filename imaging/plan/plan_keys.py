"""The keys a ``ctdrill-plan/1`` document may hold (the format: :mod:`ctdrill.imaging.plan.types`).

Read by :mod:`ctdrill.imaging.plan.plan_file`; any other key is refused, naming it.
"""

from __future__ import annotations

from ctdrill.imaging.plan.types import SERIES_HASH_KEY

_TOP_KEYS = {
    "format",
    "coordinate_system",
    "entry_mm",
    "target_mm",
    "drill",
    "drills",
    "feed_mm_s",
    "calibration",
    "margin_mm",
    "min_wall_mm",
    "site",
    "placement",
    "landmarks",
    SERIES_HASH_KEY,
    "name",
    "description",
    "comment",
    "implant",
    "arch_mm",
    "trajectories",
}
#: Keys of one item of ``trajectories`` (several trajectories in one file).
_TRAJECTORY_KEYS = {
    "name",
    "entry_mm",
    "target_mm",
    "drill",
    "drills",
    "implant",
    "feed_mm_s",
    "calibration",
    "margin_mm",
    "min_wall_mm",
    "site",
    "placement",
    "description",
    "comment",
}
#: Top-level keys a file with ``trajectories`` must not give (they belong to a trajectory).
_PER_TRAJECTORY_KEYS = _TRAJECTORY_KEYS - {"name", "description", "comment"}
_LANDMARK_KEYS = {
    "canal": {"name", "kind", "points_mm", "radius_mm", "margin_mm", "description"},
    "point": {"name", "kind", "point_mm", "points_mm", "margin_mm", "description"},
    "mask": {
        "name",
        "kind",
        "path",
        "label",
        "segment",
        "affine_lps",
        "axes",
        "margin_mm",
        "description",
    },
}
