"""The window's state as plain evented objects that import no Qt (napari's layers' manner):
:class:`~ctdrill.app.gui.state.window.WindowState` holds the series, the plans, the draft, the
path results, the rehearsal's state and the debrief, and announces each change with a typed
:class:`~ctdrill.app.gui.state.events.Event`; the window's widgets subscribe through a thin Qt
adapter (:class:`ctdrill.app.gui.document.Document`)."""
