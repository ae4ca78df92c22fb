"""The slice views' toolbar: window/level preset and readout, the tool (navigate, canal,
distance, angle, arch), and "Centre on drill" (the canal tracing's settings are in the Plan
tab's landmarks and on the panorama page)."""

from __future__ import annotations

from typing import Protocol

from PySide6.QtWidgets import (
    QButtonGroup,
    QComboBox,
    QHBoxLayout,
    QPushButton,
    QSizePolicy,
    QToolButton,
    QWidget,
)

from ctdrill.imaging.display import WINDOW_PRESETS


class ToolbarTarget(Protocol):
    """What the toolbar's controls call (:class:`ctdrill.app.gui.slice_grid.SliceGrid`)."""

    def set_window_preset(self, label: str) -> None: ...

    def set_mode(self, mode: str) -> None: ...

    def centre_on_drill(self) -> None: ...


#: The tools, with their button text and tooltip.
TOOLS: dict[str, tuple[str, str]] = {
    "navigate": (
        "Navigate",
        "Drag the implant (its apex or body: moved whole; its platform: tilted; Shift: along "
        "its axis; Ctrl on the apex: the apex alone) or the entry; a click links the views "
        "there; right-click: target (Shift: entry), right-drag: window/level",
    ),
    "canal": (
        "Canal",
        "Click along the canal to trace it (the side's canal, or the one chosen); drag a "
        "point to move it; right-click or Delete removes it",
    ),
    "distance": ("Distance", "Click two points to measure; right-click or Delete removes it"),
    "angle": ("Angle", "Three clicks: arm, vertex, arm; right-click or Delete removes it"),
    "arch": (
        "Arch",
        "Axial view: click adds an arch point on this slice, drag moves one, "
        "right-click or Delete removes one",
    ),
}


class SliceToolbar(QWidget):
    """One row above the slice views."""

    def __init__(self, grid: ToolbarTarget) -> None:
        super().__init__()
        self.grid = grid
        lay = QHBoxLayout(self)
        lay.setContentsMargins(2, 0, 2, 0)
        self.preset = QComboBox()
        self.preset.addItems(list(WINDOW_PRESETS))
        self.preset.setToolTip("Window/level preset (right-drag on a slice adjusts it)")
        self.preset.textActivated.connect(grid.set_window_preset)
        # its width is the slice area's: it must not widen it (the canvases would move)
        self.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Fixed)
        lay.addWidget(self.preset)
        lay.addSpacing(6)
        self.tool_group = QButtonGroup(self)
        self.tool_group.setExclusive(True)
        self.tool_buttons: dict[str, QToolButton] = {}
        for mode, (text, tip) in TOOLS.items():
            button = QToolButton()
            button.setText(text)
            button.setToolTip(tip)
            button.setCheckable(True)
            button.clicked.connect(lambda _c=False, m=mode: grid.set_mode(m))
            self.tool_group.addButton(button)
            self.tool_buttons[mode] = button
            lay.addWidget(button)
        self.tool_buttons["navigate"].setChecked(True)
        lay.addSpacing(6)
        self.centre = QPushButton("Centre")
        self.centre.setToolTip("Planes back through the target, views centred on the drill (C)")
        self.centre.clicked.connect(lambda _c=False: grid.centre_on_drill())
        lay.addWidget(self.centre)
        lay.addStretch(1)

    def show_mode(self, mode: str) -> None:
        """Check the button of ``mode``."""
        button = self.tool_buttons.get(mode)
        if button is not None:
            button.setChecked(True)
        else:
            self.tool_group.setExclusive(False)
            for b in self.tool_buttons.values():
                b.setChecked(False)
            self.tool_group.setExclusive(True)
