"""The document's background work: loading a series (then its bone surface, queued after the
slices' and the path's jobs so that the 2D views come first), re-contouring the surface,
planning the path whenever the plan changes (and while it is dragged) and searching nearby axes
when asked (:func:`ctdrill.app.search.suggest.suggest`). Each runs a headless
function (:mod:`ctdrill.app.gui.compute`, :func:`ctdrill.app.gui.results.compute_path_view`) in
a worker thread and hands the result to the document on the UI thread.

The path is planned at once after an edit and for every position of a drag: one computation
at a time, the latest plan next (``Runner.submit_latest``), so a fast drag never queues stale
work and the plots follow the mouse. A dragged plan is computed in two runners, each one job
at a time with the latest next: its curves and stop (``live_runner``,
:func:`~ctdrill.app.gui.results.curves_view`: a few milliseconds) go to the plots at once,
and the next position's curves start at once; the implant's check, the plan's problems and
the cross-section's readout (``check_runner``:
:func:`~ctdrill.app.gui.results.completed_view`,
:func:`ctdrill.app.gui.readouts.implant_readout`, its walls on the full grid) follow for the
banner and the readout, for the latest position whose curves are drawn, at most every
:data:`LIVE_CHECKS_EVERY_MS` during the drag (their Python holds the interpreter lock the UI
thread and the next curves need) and at once at its end, so the plots never wait for them.
Any other path result is followed by the readout in a runner of its own.
"""

from __future__ import annotations

import sys
import time
from typing import Any

from PySide6.QtCore import QObject, QTimer, Signal

from ctdrill import jit
from ctdrill.app.gui import compute
from ctdrill.app.gui.document import Document
from ctdrill.app.gui.readouts import ImplantReadout, implant_readout
from ctdrill.app.gui.results import PathView, completed_view, compute_path_view, curves_view
from ctdrill.app.gui.workers import Debouncer, Runner
from ctdrill.app.search.candidates import SearchSpace
from ctdrill.app.search.suggest import Suggestion, suggest
from ctdrill.engine.plans import plan_calibration
from ctdrill.imaging.display import BONE_SURFACE_HU
from ctdrill.imaging.plan.types import Plan

#: The interpreter's switch interval in the window's process, s: a worker running Python
#: (the path's glue between its compiled kernels, the checks) hands the interpreter lock to
#: the UI thread within this. At Python's default, 5 ms, each wake-up of the UI thread (a
#: mouse move, a timer, a paint, a worker's result) waited up to 5 ms behind a busy worker,
#: and a drag's events queued behind them: 7-9 of 60 mouse moves a second were handled.
UI_SWITCH_INTERVAL_S = 0.0005

#: Least time between the starts of a drag's checks, ms: the implant's check and the readout
#: (tens of milliseconds of Python, holding the interpreter lock the UI thread and the next
#: curves need) follow the drag ten times a second instead of back to back; the drag's end
#: starts the last position's at once.
LIVE_CHECKS_EVERY_MS = 100

#: Delay between the last plan edit and the recomputation, ms: none (a computation at a
#: time, latest plan next, replaces the wait; the worker starts once the edit's events are
#: served, before its drawing steps: ``Debouncer``).
DEBOUNCE_MS = 0


class Controller(QObject):
    """Runs the document's computations.

    Signals
    -------
    loaded(result) : a ``compute.Loaded`` (already in the document) or a ``SeriesChoice``
        (the window asks which series).
    failed(stage, exc, traceback) : ``stage`` is ``load``, ``path``, ``surface`` or ``suggest``
        (``suggest`` only for bugs: bad input is the document's ``suggest_status``).
    """

    loaded = Signal(object)
    failed = Signal(str, object, str)

    def __init__(self, doc: Document, parent: QObject | None = None) -> None:
        super().__init__(parent)
        sys.setswitchinterval(min(sys.getswitchinterval(), UI_SWITCH_INTERVAL_S))
        self.doc = doc
        self.iso_hu = BONE_SURFACE_HU
        self.load_runner = Runner(self._loaded, self._fail("load"), parent=self)
        self.path_runner = Runner(self._path_done, self._path_failed, parent=self)
        self.surface_runner = Runner(doc.set_surface, self._fail("surface"), parent=self)
        self.suggest_runner = Runner(self._suggest_done, self._suggest_failed, parent=self)
        self.live_runner = Runner(self._curves_done, self._fail("path"), parent=self)
        self.check_runner = Runner(self._live_done, self._fail("path"), parent=self)
        #: A drag's checks waiting for their turn (:data:`LIVE_CHECKS_EVERY_MS`), and when
        #: the last ones started (``time.monotonic``).
        self._checks_due: Any = None
        self._checks_at = -float("inf")
        self._checks_timer = QTimer(self)
        self._checks_timer.setSingleShot(True)
        self._checks_timer.timeout.connect(self._start_checks)
        self.readout_runner = Runner(self._readout_done, self._fail("path"), parent=self)
        self.debounce = Debouncer(self.recompute, DEBOUNCE_MS, parent=self)
        self._computing: Plan | None = None
        self._live_for: Plan | None = None
        self._suggesting: Plan | None = None
        doc.live.plan_dragged.connect(self._dragged)
        doc.live.plan_dragged.connect(self._drag_ended)
        doc.path_changed.connect(self._read_out)
        doc.live.path_changed.connect(self._read_out)
        doc.suggestion_requested.connect(self.run_suggest)
        doc.plan_changed.connect(lambda _plan: self.debounce.poke())
        doc.volume_changed.connect(lambda _volume: self.recompute())

    def _fail(self, stage: str) -> Any:
        return lambda exc, tb: self.failed.emit(stage, exc, tb)

    def load(self, folder: str, *, series_uid: str | None, ask_series: bool) -> None:
        """Load ``folder`` in the background (``ask_series``: a folder of several CT stacks
        gives a ``SeriesChoice`` instead)."""
        jit.preload()  # the path's kernels load beside the series, not after it
        iso, ask = self.iso_hu, ask_series
        self.load_runner.submit(
            lambda: compute.load_case(
                folder, series_uid=series_uid, iso_hu=iso, ask_series=ask, surface=False
            )
        )

    def _loaded(self, loaded: compute.Loaded | compute.SeriesChoice) -> None:
        if isinstance(loaded, compute.Loaded):
            self.doc.set_volume(loaded.volume, loaded.path, loaded.surface)
            if loaded.surface is None:  # contoured after the slices' and the path's jobs
                self.set_iso(loaded.iso_hu)
        self.loaded.emit(loaded)

    def recompute(self) -> None:
        """Plan the path of the document's current trajectory through its volume now (unless
        already computed for it)."""
        self.debounce.cancel()
        volume, plan = self.doc.volume, self.doc.plan
        if volume is None or plan is None:
            return
        if self.doc.path is not None and self.doc.path.plan is plan:
            return  # already computed for this trajectory (switching back to it)
        live_busy = self.live_runner.busy or self.check_runner.busy or self._checks_due is not None
        if live_busy and self._live_for is plan:
            return  # a drag's last position: its computation is under way
        self._computing = plan
        hu = self.doc.hu_uncertainty
        plans = self.doc.plans
        self.path_runner.submit_latest(lambda: compute_path_view(volume, plan, hu, plan_set=plans))

    def set_debounce(self, ms: int) -> None:
        """Wait ``ms`` after an edit before planning its path (0: at once)."""
        self.debounce.set_interval(ms)

    def _dragged(self, plan: Plan | None) -> None:
        """Plan the curves of a dragged plan now (one at a time, the latest next); its checks
        follow (:meth:`_curves_done`)."""
        volume = self.doc.volume
        if plan is None or volume is None:
            return
        self._live_for = plan
        hu = self.doc.hu_uncertainty
        others = tuple(plan if p is self.doc.plan else p for p in self.doc.plans)

        def curves() -> tuple[Plan, PathView | str | None, Any]:
            try:
                return plan, curves_view(volume, plan, hu, plan_set=others), checks
            except ValueError as exc:  # bad input (an axis leaving the scan): said, no curve
                return plan, str(exc), checks

        def checks(first: PathView | None) -> tuple[PathView, ImplantReadout] | tuple[Plan, str]:
            try:
                view = (
                    compute_path_view(volume, plan, hu, plan_set=others)
                    if first is None  # a drill sequence: in one stage
                    else completed_view(volume, first)
                )
            except ValueError as exc:
                return plan, str(exc)
            # the cross-section's readout with every position checked (it follows the drag)
            return view, implant_readout(volume, plan, view)

        self.live_runner.submit_latest(curves)

    def _read_out(self, view: PathView | None) -> None:
        """The readout of the plan a path result is for (after it: the plots come first)."""
        volume = self.doc.volume
        if view is None or volume is None:
            return
        if self.doc.live.dragging:
            return  # a dragged plan's readout comes with its path (``_dragged``)

        def job() -> tuple[Plan, ImplantReadout]:
            return view.plan, implant_readout(volume, view.plan, view)

        self.readout_runner.submit_latest(job)

    def _readout_done(self, result: tuple[Plan, ImplantReadout]) -> None:
        self.doc.live.set_readout(*result)

    def _curves_done(self, result: tuple[Plan, PathView | str | None, Any]) -> None:
        """A dragged plan's curves: the plots show them at once; its checks are computed
        next (the latest plan whose curves came, one at a time)."""
        plan, first, checks = result
        if isinstance(first, str):
            self.doc.live.fail(plan, first)
            return
        if first is not None:
            self.doc.live.offer_curves(first)
        self._checks_due = lambda: checks(first)
        wait_ms = LIVE_CHECKS_EVERY_MS - 1e3 * (time.monotonic() - self._checks_at)
        if not self.doc.live.dragging or wait_ms <= 0:
            self._start_checks()
        elif not self._checks_timer.isActive():
            self._checks_timer.start(int(wait_ms) + 1)

    def _drag_ended(self, plan: Plan | None) -> None:
        if plan is None:  # the last position's checks now
            self._start_checks()

    def _start_checks(self) -> None:
        """Start the latest dragged position's checks (one at a time, the latest next)."""
        self._checks_timer.stop()
        job, self._checks_due = self._checks_due, None
        if job is not None:
            self._checks_at = time.monotonic()
            self.check_runner.submit_latest(job)

    def _live_done(self, result: tuple[PathView, ImplantReadout] | tuple[Plan, str]) -> None:
        view, extra = result
        if isinstance(view, PathView) and isinstance(extra, ImplantReadout):
            self.doc.set_path(view)
            if self.doc.live.dragging:
                self.doc.live.set_readout(view.plan, extra)
        elif isinstance(view, Plan) and isinstance(extra, str):
            self.doc.live.fail(view, extra)

    def _path_done(self, view: Any) -> None:
        self.doc.set_path(view)

    def _path_failed(self, exc: BaseException, tb: str) -> None:
        if self._computing is not None:
            self.doc.set_path_failed(self._computing, str(exc))
        self.failed.emit("path", exc, tb)

    def set_iso(self, iso_hu: float) -> None:
        """Re-contour the bone surface at ``iso_hu`` (in the background)."""
        self.iso_hu = iso_hu
        volume = self.doc.volume
        if volume is not None:
            self.surface_runner.submit(
                lambda: compute.volume_surface(
                    volume, iso_hu=iso_hu, max_triangles=compute.FIRST_TRIANGLES
                )
            )

    def run_suggest(self, space: SearchSpace) -> None:
        """Search the axes around the document's plan (in the background)."""
        volume, plan = self.doc.volume, self.doc.plan
        if volume is None or plan is None:
            return
        self._suggesting = plan

        def job() -> tuple[Plan, Suggestion]:
            return plan, suggest(volume, plan, plan_calibration(plan), space)

        self.suggest_runner.submit(job)

    def _suggest_done(self, result: tuple[Plan, Suggestion]) -> None:
        self.doc.set_suggestion(*result)

    def _suggest_failed(self, exc: BaseException, tb: str) -> None:
        if self._suggesting is not None:
            self.doc.set_suggestion_failed(self._suggesting, f"error: {exc}")
        if not isinstance(exc, ValueError):  # the packages' *InputError family: bad input
            self.failed.emit("suggest", exc, tb)

    def cancel(self) -> None:
        """Drop every running job (window closing)."""
        for runner in (
            self.load_runner,
            self.path_runner,
            self.live_runner,
            self.check_runner,
            self.readout_runner,
            self.surface_runner,
            self.suggest_runner,
        ):
            runner.cancel()
