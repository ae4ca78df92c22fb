"""The window's Report command: the PDF of the current plan (``ctdrill report``'s clinical
summary), written in the background.

The trajectories as they are in the window (saved or not) are written to a temporary plan file
beside nothing the user sees, and :func:`ctdrill.app.report.build.write_report` computes and
writes the report from the open series exactly as ``ctdrill report`` does; the status bar says
where it went, or why not.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

from PySide6.QtCore import QObject, Signal

from ctdrill.app.gui.document import Document
from ctdrill.app.gui.workers import Runner
from ctdrill.imaging.plan.write import write_plans


class ReportCommand(QObject):
    """Writes the report of ``doc``'s plans on its series (one at a time)."""

    finished = Signal(str)  # what the status bar says

    def __init__(self, doc: Document, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self.doc = doc
        self.runner = Runner(self._done, self._failed, parent=self)

    @property
    def busy(self) -> bool:
        """A report is being written."""
        return self.runner.busy

    def write(self, out: str | Path, *, appendix: bool = False) -> bool:
        """Start writing the report to ``out`` (PDF); False (and why, in :attr:`finished`)
        when there is nothing to report."""
        doc = self.doc
        if doc.volume is None or not doc.volume_path:
            self.finished.emit("report: open a series first")
            return False
        if not doc.plans:
            self.finished.emit("report: place a trajectory first")
            return False
        plans, series = tuple(doc.plans), doc.volume_path
        uid = doc.volume.info.series_uid
        target = Path(out)

        def job() -> str:
            from ctdrill.app.report.build import write_report

            with tempfile.TemporaryDirectory(prefix="ctdrill-report-") as tmp:
                plan_file = Path(tmp) / "plan.json"
                write_plans(plans, plan_file, series_uid=uid)
                path, n = write_report(Path(series), [plan_file], target, appendix=appendix)
            return f"wrote {path} ({n} pages)"

        self.runner.submit(job)
        self.finished.emit(f"writing the report to {target} ...")
        return True

    def _done(self, message: object) -> None:
        self.finished.emit(str(message))

    def _failed(self, exc: BaseException, _tb: str) -> None:
        self.finished.emit(f"error: report not written: {exc}")
