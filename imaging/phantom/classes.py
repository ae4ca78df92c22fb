"""The phantom's bone classes, apart from :mod:`ctdrill.imaging.phantom.field` (NumPy).

``ctdrill phantom --help`` lists them, so they live where building the command-line parser
imports nothing heavy; :mod:`ctdrill.imaging.phantom.field` and ``.mandible`` re-export them.
"""

#: Misch class -> (trabecular HU, cortical HU, cortical thickness mm). Trabecular values sit
#: inside each class's HU band (D1 > 1250, D2 850-1250, D3 350-850, D4 150-350, D5 < 150).
MISCH_CLASSES: dict[str, tuple[float, float, float]] = {
    "D1": (1400.0, 1800.0, 2.0),
    "D2": (1050.0, 1700.0, 2.0),
    "D3": (600.0, 1600.0, 1.6),
    "D4": (250.0, 1500.0, 1.5),
    "D5": (100.0, 1500.0, 1.5),
}
