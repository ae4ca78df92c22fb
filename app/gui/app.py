"""Start the window: size it, open the case, and (for ``--screenshot``) save the window once it
has drawn the case, then quit."""

from __future__ import annotations

import sys
from pathlib import Path

from PySide6.QtCore import QSettings, QTimer
from PySide6.QtWidgets import QApplication

from ctdrill.app.gui import feature_hook  # noqa: F401  (first: PySide6's hook made cheap)
from ctdrill.app.gui.main_window import MainWindow
from ctdrill.app.gui.screenshot import qimage_to_rgb, region_stats, widget_rect
from ctdrill.imaging.plan.implants import ImplantSpec
from ctdrill.imaging.plan.types import Plan
from ctdrill.model.band import HuUncertainty

#: Preferred and minimum window size, logical pixels (DESIGN.md section 4).
PREFERRED_SIZE = (1440, 900)
MIN_SIZE = (1280, 800)


def window_size(available: tuple[int, int]) -> tuple[int, int]:
    """The window size for a screen with ``available`` (width, height): the preferred size,
    cut to the screen, but never under 1280x800 unless the screen is smaller."""
    aw, ah = available
    w = min(PREFERRED_SIZE[0], aw) if aw >= MIN_SIZE[0] else aw
    h = min(PREFERRED_SIZE[1], ah) if ah >= MIN_SIZE[1] else ah
    return max(w, min(MIN_SIZE[0], aw)), max(h, min(MIN_SIZE[1], ah))


def application() -> QApplication:
    """The running QApplication (created when missing)."""
    app = QApplication.instance()
    if isinstance(app, QApplication):
        return app
    return QApplication(sys.argv[:1])


def make_window(settings: QSettings | None = None) -> MainWindow:
    """A sized, shown main window."""
    app = application()
    window = MainWindow(settings=settings)
    screen = app.primaryScreen()
    avail = screen.availableGeometry() if screen is not None else None
    size = window_size((avail.width(), avail.height()) if avail is not None else PREFERRED_SIZE)
    window.resize(*size)
    window.show()
    return window


def run_gui(
    *,
    dicom: Path | None = None,
    plans: tuple[Plan, ...] = (),
    implants: tuple[ImplantSpec, ...] | None = None,
    screenshot: Path | None = None,
    quit_after_s: float | None = None,
    settings: QSettings | None = None,
    hu_uncertainty: HuUncertainty | None = None,
    instructor: bool = False,
) -> int:
    """Run the window until it is closed (or ``quit_after_s``). Returns the exit code.

    ``instructor``: the command line opened a blind trial with the instructor's key (``--key``):
    its CT opens outside the blind mode.

    With ``screenshot``, the composited window is saved as soon as the case is drawn (path
    planned, or right after showing when no series is given), and the window quits.
    A load that fails on bad input is re-raised after the loop so the CLI reports it.
    ``plans`` (every trajectory of the plan files) and ``implants`` (the implant library,
    ``--implants``) were read by the caller (a file that cannot be read never reaches the
    window).
    """
    app = application()
    window = make_window(settings)
    window.doc.hu_uncertainty = hu_uncertainty  # ``--hu-sigma``: enters the force band
    if implants is not None:  # ``--implants``: the library the implant picker offers
        window.plan_panel.implant.set_library(implants)
    window.instructor = instructor  # ``--key``: a trial's CT may open outside its blind mode
    window.unattended = screenshot is not None or quit_after_s is not None
    window.ask_series = not window.unattended  # unattended: take the largest series
    if plans:
        window.use_plans(plans, plans[0].source)
        window.show_trial(sorted({p.source for p in plans if p.source}))  # a blind trial's?
    if dicom is not None:
        window.open_folder(dicom)
    state = {"saved": False}

    def take() -> None:
        if screenshot is None or state["saved"]:
            return
        state["saved"] = True
        image = window.grab_composite()
        if not image.save(str(screenshot)):
            window.last_error = f"could not write the screenshot {screenshot}"
        else:
            rect = widget_rect(window.view3d, window)
            stats = region_stats(
                qimage_to_rgb(image), (rect.x(), rect.y(), rect.width(), rect.height())
            )
            if not stats.drawn:
                sys.stderr.write(f"warning: the 3D view looks blank in {screenshot}\n")
        app.quit()

    if window.unattended:  # a bad series ends the run (reported after the loop)
        window.load_failed.connect(lambda _msg: app.quit())
    if screenshot is not None:
        if dicom is None:
            QTimer.singleShot(500, take)
        else:  # once both the path (or its refusal) and the slices are drawn
            # the 3D view's surface settled: the finer one its frame time affords is drawn
            pending = {"path", "slices", "surface"} if plans else {"slices", "surface"}

            def settled() -> None:  # every queued drawing step has run: the views are drawn
                if window.ui_steps.pending:
                    QTimer.singleShot(100, settled)
                else:
                    QTimer.singleShot(300, take)

            def arrived(what: str) -> None:
                pending.discard(what)
                if not pending:
                    settled()

            window.path_updated.connect(lambda: arrived("path"))
            window.path_failed.connect(lambda _msg: arrived("path"))
            window.slices_updated.connect(lambda: arrived("slices"))
            window.view3d.surface_settled.connect(lambda: arrived("surface"))

    def timeout() -> None:
        take()
        app.quit()

    if quit_after_s is not None:
        QTimer.singleShot(int(quit_after_s * 1000), timeout)
    app.exec()
    window.close()
    if window.load_error is not None:
        raise window.load_error
    if window.internal_error:
        sys.stderr.write(window.internal_error + "\n")
        return 1
    return 0
