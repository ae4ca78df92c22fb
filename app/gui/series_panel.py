"""The Series tab: why rehearsal is blocked, the loader's warnings, the path's warnings."""

from __future__ import annotations

from PySide6.QtWidgets import QLabel, QListWidget, QVBoxLayout, QWidget

from ctdrill.imaging import LoadWarning


class SeriesPanel(QWidget):
    """Warnings of the open series and of the planned path, and the blocking reason."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.block_label = QLabel("")
        self.block_label.setWordWrap(True)
        self.block_label.setStyleSheet("color:#b71c1c; font-weight:bold")
        self.warnings_list = QListWidget()
        self.path_warnings_list = QListWidget()
        lay = QVBoxLayout(self)
        lay.addWidget(self.block_label)
        lay.addWidget(QLabel("Loader warnings"))
        lay.addWidget(self.warnings_list)
        lay.addWidget(QLabel("Along the drill path"))
        lay.addWidget(self.path_warnings_list)

    def set_load_warnings(self, warnings: tuple[LoadWarning, ...]) -> None:
        """Show the loader's warnings (``code: message``)."""
        self.warnings_list.clear()
        for w in warnings:
            self.warnings_list.addItem(f"{w.code}: {w.message}")

    def set_path_warnings(
        self, warnings: tuple[LoadWarning, ...], already: tuple[LoadWarning, ...]
    ) -> None:
        """Show the path's warnings that the loader list does not already hold."""
        seen = {(w.code, w.message) for w in already}
        self.path_warnings_list.clear()
        for w in warnings:
            if (w.code, w.message) not in seen:
                self.path_warnings_list.addItem(f"{w.code}: {w.message}")

    def set_block(self, reason: str | None) -> None:
        """Say why rehearsal is disabled (None: it is not)."""
        self.block_label.setText("" if not reason else f"Rehearsal disabled: {reason}")
