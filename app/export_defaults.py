"""Defaults of the headless export that ``ctdrill export --help`` shows.

Kept apart from :mod:`ctdrill.app.export` (NumPy, the pipeline, imaging) so that building the
command-line parser imports nothing heavy; :mod:`ctdrill.app.export` re-exports them.
"""

#: Sample rate of ``force.csv``, Hz.
DEFAULT_RATE_HZ = 1000.0
