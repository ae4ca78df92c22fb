"""The implant of the current trajectory, picked from the library (a row of the Plan tab).

The library is :func:`ctdrill.imaging.plan.implants.load_implant_library`: the generic sizes
shipped with ctdrill, extended by ``ctdrill gui --implants FILE``. An implant a plan file
spelled out that the library lacks is offered too, marked "(from the plan)". Picking one is a
plan edit (an undo step); the apex sits at the planned target
(:func:`~ctdrill.imaging.plan.implants.implant_placement`).
"""

from __future__ import annotations

from collections.abc import Sequence

from PySide6.QtCore import Qt
from PySide6.QtWidgets import QComboBox

from ctdrill.app.gui import planning
from ctdrill.app.gui.document import ViewContext
from ctdrill.imaging.plan.implants import ImplantSpec, load_implant_library
from ctdrill.imaging.plan.types import Plan

#: The first entry: no implant on this trajectory.
NO_IMPLANT = "(no implant)"
FROM_PLAN = "(from the plan)"


def implant_text(spec: ImplantSpec) -> str:
    """A picker entry: ``tapered 4.1 x 10  (4.1 x 10 mm, apex 2.9 mm round)``."""
    shape = (
        "cylindrical"
        if spec.apex_diameter_mm == spec.diameter_mm
        else f"apex {spec.apex_diameter_mm:g} mm"
    )
    return f"{spec.name}  ({spec.size_text}, {shape}, {spec.apex})"


class ImplantPicker(QComboBox):
    """Pick the current trajectory's implant from the library."""

    def __init__(self, ctx: ViewContext, library: Sequence[ImplantSpec] | None = None) -> None:
        super().__init__()
        self.ctx = ctx
        self.library: tuple[ImplantSpec, ...] = (
            load_implant_library() if library is None else tuple(library)
        )
        self._specs: list[ImplantSpec | None] = []
        self._updating = False
        self.setToolTip(
            "The implant placed on the current trajectory: its apex at the target, its body "
            "drawn in every view (library: ctdrill gui --implants FILE adds yours)"
        )
        self.activated.connect(self._picked)
        self.show_plan(None)

    def set_library(self, library: Sequence[ImplantSpec]) -> None:
        """Offer ``library`` (e.g. read from ``--implants``)."""
        self.library = tuple(library)
        self.show_plan(self.ctx.doc.plan)

    def show_plan(self, plan: Plan | None) -> None:
        """List the library with ``plan``'s implant selected (no edit is made)."""
        current = None if plan is None else plan.implant
        specs: list[ImplantSpec | None] = [None, *self.library]
        if current is not None and current not in self.library:
            specs.append(current)
        if specs == self._specs:  # the same list (an edit elsewhere in the plan): select only
            self._updating = True
            try:
                self.setCurrentIndex(specs.index(current))
            finally:
                self._updating = False
            return
        self._updating = True
        try:
            self.clear()
            for spec in specs:
                if spec is None:
                    self.addItem(NO_IMPLANT)
                else:
                    extra = f"  {FROM_PLAN}" if spec not in self.library else ""
                    self.addItem(implant_text(spec) + extra)
                    self.setItemData(
                        self.count() - 1, implant_text(spec), Qt.ItemDataRole.ToolTipRole
                    )
            self._specs = specs
            self.setCurrentIndex(specs.index(current))
        finally:
            self._updating = False

    @property
    def spec(self) -> ImplantSpec | None:
        """The implant selected (None: none)."""
        index = self.currentIndex()
        return self._specs[index] if 0 <= index < len(self._specs) else None

    def pick(self, name: str | None) -> bool:
        """Select the library implant called ``name`` (None: no implant), as a user would."""
        for index, spec in enumerate(self._specs):
            if (spec is None and name is None) or (spec is not None and spec.name == name):
                self.setCurrentIndex(index)
                self._picked(index)
                return True
        return False

    def _picked(self, index: int) -> None:
        doc = self.ctx.doc
        plan = doc.plan
        if self._updating or plan is None or not 0 <= index < len(self._specs):
            return
        spec = self._specs[index]
        if spec == plan.implant:
            return
        name = "remove implant" if spec is None else f"pick implant {spec.name!r}"
        try:
            new = planning.with_implant(plan, spec)
        except ValueError as exc:
            doc.edit_refused.emit(f"error: {exc}")
            self.show_plan(doc.plan)
            return
        if not doc.set_plan(new, edit=name):
            self.show_plan(doc.plan)  # refused: the implant that holds
