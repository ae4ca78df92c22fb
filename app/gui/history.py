"""Undo and redo of plan edits: a headless stack of document states (no Qt).

A state is what an edit changes: the trajectories (frozen :class:`Plan` objects, shared, never
copied), which one is current, and the suggestion kept with the plan (with the candidate
adopted from it). Every edit pushes the state *before* it under the edit's name; undo restores
that state and keeps the undone one for redo; a new edit clears the redo side.
"""

from __future__ import annotations

from dataclasses import dataclass

from ctdrill.app.search.suggest import Suggestion
from ctdrill.imaging.plan.types import Plan

#: Most undo steps kept (the oldest are dropped first): states share their plans, so a step
#: costs a tuple of references.
MAX_STEPS = 200


@dataclass(frozen=True)
class State:
    """The part of the document an edit changes."""

    plans: tuple[Plan, ...]
    current: int
    suggestion: Suggestion | None = None
    adopted: int | None = None


class History:
    """The undo and redo stacks of named states."""

    def __init__(self, max_steps: int = MAX_STEPS) -> None:
        self.max_steps = max_steps
        self._undo: list[tuple[str, State]] = []
        self._redo: list[tuple[str, State]] = []

    def push(self, name: str, before: State) -> None:
        """An edit called ``name`` left ``before``: it can be undone; redo is cleared."""
        self._undo.append((name, before))
        del self._undo[: -self.max_steps]
        self._redo.clear()

    def undo(self, now: State) -> State | None:
        """The state before the last edit (None: nothing to undo); ``now`` becomes redoable."""
        if not self._undo:
            return None
        name, before = self._undo.pop()
        self._redo.append((name, now))
        return before

    def redo(self, now: State) -> State | None:
        """The state the last undo left (None: nothing to redo); ``now`` becomes undoable."""
        if not self._redo:
            return None
        name, after = self._redo.pop()
        self._undo.append((name, now))
        return after

    def clear(self) -> None:
        """Forget every step (a new plan file, a new series)."""
        self._undo.clear()
        self._redo.clear()

    @property
    def undo_name(self) -> str | None:
        """What undo would revert (None: nothing)."""
        return self._undo[-1][0] if self._undo else None

    @property
    def redo_name(self) -> str | None:
        """What redo would apply again (None: nothing)."""
        return self._redo[-1][0] if self._redo else None
