"""The ctdrill desktop window (PySide6 + pyvistaqt): ``ctdrill gui``.

Logic lives in headless modules (``slices``, ``scene``, ``planning``, ``plots``, ``compute``,
``results``, ``rehearsal``, ``session_process``); the widgets only show their results.
"""
