"""Defaults of the calibration fit that ``ctdrill calibrate --help`` shows.

Kept apart from :mod:`ctdrill.model.fit` (NumPy, SciPy) so that building the command-line
parser imports nothing heavy; :mod:`ctdrill.model.fit` re-exports them.
"""

#: The paper's analysis window: "data were collected for cutting depths between 1 mm and 8 mm".
DEFAULT_DEPTH_WINDOW_MM: tuple[float, float] = (1.0, 8.0)
