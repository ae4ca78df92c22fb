"""The canal tubes of the slice views waiting for a path, computed in a worker meanwhile.

After a plan edit only the view acted on draws at once (:mod:`ctdrill.app.gui.overlay_pacing`);
the others draw with the path result. A canal point added or removed changes every view's
tube field (:func:`~ctdrill.app.gui.sections.tube_field`, 3-5 ms of NumPy a view): those the
waiting views will draw are computed in the background while the path is planned, into the
cache their drawing reads (:func:`~ctdrill.app.gui.slice_overlays.prefetch_tubes`); one still
missing when its view draws is computed there, as before.
"""

from __future__ import annotations

from PySide6.QtCore import QObject

from ctdrill.app.gui.slice_overlays import TubeRequest, prefetch_tubes, tube_cached
from ctdrill.app.gui.workers import Runner


class TubePrefetch(QObject):
    """One job at a time (the latest requests next, with those still waiting)."""

    def __init__(self, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self._due: list[TubeRequest] = []
        self.runner = Runner(
            lambda _n: self._due.clear(),
            lambda _exc, _tb: self._due.clear(),  # drawn from scratch by their views
            parent=self,
        )

    def fetch(self, requests: list[TubeRequest]) -> None:
        """Compute the fields of ``requests`` not kept yet, in the background."""
        missing = [r for r in requests if not tube_cached(r)]
        if missing:  # with those still waiting for a job that a newer one replaces
            self._due.extend(missing)
            due = list(self._due)
            self.runner.submit_latest(lambda: prefetch_tubes(due))
