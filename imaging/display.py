"""How CT numbers are shown: window/level presets and bone iso-surface levels, in HU.

Display conventions of the Hounsfield scale, defined once for everything that draws a CT: the
window's slice views and 3D view, the panoramic reformat's images and the report. They choose
what is visible, never what is computed: where bone begins for the model and the planner is
:data:`ctdrill.imaging.misch.BONE_HU` (the Misch D4 edge, 150 HU); the surface drawn at
:data:`BONE_SURFACE_HU` lies inside that bone, where clinical CT shows a clean outline.
"""

from __future__ import annotations

#: Window/level presets, ``name -> (level_hu, width_hu)``.
WINDOW_PRESETS: dict[str, tuple[float, float]] = {
    "bone": (500.0, 2000.0),
    "implant planning": (800.0, 3000.0),
    "soft tissue": (40.0, 400.0),
    "CBCT": (1000.0, 4000.0),
}

#: The bone surface of the 3D view and the report on clinical CT, HU.
BONE_SURFACE_HU = 300.0
#: Bone iso-surface presets, ``label -> HU``; the first is :data:`BONE_SURFACE_HU`.
SURFACE_PRESETS: dict[str, float] = {
    f"CT bone ({BONE_SURFACE_HU:g} HU)": BONE_SURFACE_HU,
    "CBCT bone (500 HU)": 500.0,
    "cortical (1000 HU)": 1000.0,
    "soft tissue (-300 HU)": -300.0,
}
