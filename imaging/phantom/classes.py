"""The phantom's bone classes, apart from :mod:`ctdrill.imaging.phantom.field` (NumPy).

``ctdrill phantom --help`` lists them, so they live where building the command-line parser
imports nothing heavy; :mod:`ctdrill.imaging.phantom.field` and ``.mandible`` re-export them.
"""

#: Misch class -> (trabecular HU, cortical HU, cortical thickness mm) of the phantom. Each
#: trabecular value sits inside its class's band (:mod:`ctdrill.imaging.misch` owns the bands;
#: tests/imaging/test_misch.py checks it).
MISCH_CLASSES: dict[str, tuple[float, float, float]] = {
    "D1": (1400.0, 1800.0, 2.0),
    "D2": (1050.0, 1700.0, 2.0),
    "D3": (600.0, 1600.0, 1.6),
    "D4": (250.0, 1500.0, 1.5),
    "D5": (100.0, 1500.0, 1.5),
}
