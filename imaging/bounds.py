"""The world frame's bound: the largest coordinate magnitude ctdrill accepts, LPS mm.

One owner for a plan's points (the plan reader; the engine refuses a trajectory or landmark
point beyond it built in code) and a volume's voxel corners (the grid check): 100 m is beyond
any scanner's frame, and keeps every product of coordinates finite in float32.
"""

from __future__ import annotations

#: Largest accepted coordinate magnitude, mm (plan points, voxel corners).
MAX_COORDINATE_MM = 1e5
