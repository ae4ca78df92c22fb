"""The Hounsfield scale's anchor, shared by every room: air is -1000 HU.

CT numbers are attenuation relative to water (0 HU) with air at -1000 HU (DESIGN.md 1.1).
Both rooms read it and neither may import the other, so it lives here, beside
:mod:`ctdrill.safeio`:

- ``imaging`` samples what lies outside the volume as air (``outside_hu=AIR_HU``), fills the
  phantom's air with it and anchors grey-value calibration on it;
- ``model`` defines ``C' = HU - AIR_HU`` (``= HU + 1000``, attenuation relative to air);
- ``app`` draws and samples with the same value.
"""

#: CT number of air, HU.
AIR_HU: float = -1000.0
