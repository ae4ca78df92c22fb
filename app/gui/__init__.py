"""The ctdrill desktop window (PySide6; VTK off screen for the 3D view): ``ctdrill gui``.

Logic lives in headless modules (``slices``, ``scene``, ``planning``, ``plots``, ``compute``,
``results``, ``rehearsal``, ``session_process``); the widgets only show their results.
"""
