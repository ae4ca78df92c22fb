"""The window's state: the one evented object every view draws from; it imports no Qt.

The CT volume (with its bone surface), the plan's trajectories, the path computed for the
current one, the rehearsal's state and the debrief live here and nowhere else. A view
subscribes to the events it needs (through the Qt adapter,
:class:`ctdrill.app.gui.document.Document`) and changes the state only through its methods
(napari's model/view split); the computing happens in headless functions
(:mod:`ctdrill.app.gui.compute`, :mod:`ctdrill.app.gui.results`) run by
:class:`ctdrill.app.gui.controller.Controller`.

A plan holds several trajectories (one per implant, :attr:`WindowState.plans`); one is current
(:attr:`WindowState.plan`): the panels edit it and the path (force, clearance, stop) is computed
for it. Paths already computed are kept per trajectory object, so switching back shows them at
once. Every plan edit (a trajectory moved, its drill, implant or landmarks changed, the arch,
a trajectory added, removed or renamed, a suggested axis adopted) is a named undo step
(:mod:`ctdrill.app.gui.history`); opening a plan file starts a new history. The volume is not
part of it.

A suggestion (``ctdrill suggest`` run on the current trajectory, :mod:`ctdrill.app.search`) is
kept with the plan it was computed for: adopting one of its candidates replaces the plan's
axis and keeps the suggestion (marked adopted); any other plan edit, selecting another
trajectory or a new series drops it.

The plan is locked while a rehearsal runs: the device holds the force table of the plan it was
armed with, so an edit then would make the views show a stop the device does not enforce.
Every edit (undo, redo and selecting another trajectory included) is refused then, with
``edit_refused`` saying why.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from ctdrill.app.gui.history import History, State
from ctdrill.app.gui.planning import edit_name, with_shared
from ctdrill.app.gui.results import PathView
from ctdrill.app.gui.state.events import Event
from ctdrill.app.search.candidates import SearchSpace
from ctdrill.app.search.suggest import Suggestion
from ctdrill.imaging import CTVolume
from ctdrill.imaging.plan.types import Plan
from ctdrill.model.band import HuUncertainty

#: What ``edit_refused`` says while a rehearsal runs.
LOCKED_MESSAGE = "the plan is locked while a rehearsal runs: stop the rehearsal to edit it"
#: Path results kept for trajectories other than the current one (oldest dropped first).
PATH_CACHE_SIZE = 32


class WindowState:
    """Volume, trajectories, path result and rehearsal state, with an event per change.

    Events
    ------
    volume_changed(volume) : a new series is open (``surface`` is set before).
    surface_changed(surface) : a new bone surface (new series or iso-surface preset).
    plans_changed(plans) : the trajectories, or which one is current, changed (every change;
        emitted before ``plan_changed``).
    plan_changed(plan) : the current trajectory (or None) changed or another one was selected;
        the path result is reset (to the one already computed for it, if any, announced by
        ``path_changed`` right after).
    history_changed() : what undo / redo would do changed (``history.undo_name``).
    path_changed(view) : a path result for the current plan (a ``PathView``), or None with
        ``path_error`` saying why (empty: not computed yet).
    rehearsal_changed(running) : a rehearsal started or ended.
    live_depth_changed(depth_mm) : the drill depth reported by the device.
    edit_refused(message) : a plan change refused (locked, or an invalid edit).
    suggestion_requested(space) : a search around the plan is asked for (the controller runs
        it; ``space`` a ``SearchSpace``).
    suggestion_changed(suggestion) : a search started (None, ``suggest_status`` "running"),
        finished (a ``Suggestion``), failed (None, the message in ``suggest_status``), was
        dropped (None) or one of its candidates was adopted.
    """

    volume_changed = Event(object)
    surface_changed = Event(object)
    plans_changed = Event(object)
    plan_changed = Event(object)
    history_changed = Event()
    path_changed = Event(object)
    rehearsal_changed = Event(bool)
    live_depth_changed = Event(float)
    edit_refused = Event(str)
    suggestion_requested = Event(object)
    suggestion_changed = Event(object)
    debrief_changed = Event(object)  # the last rehearsal's debrief (app/gui/debrief.Debrief)

    def __init__(self) -> None:
        self.volume: CTVolume | None = None
        self.volume_path = ""
        self.surface: Any = None  # pyvista.PolyData of the bone surface
        #: Every trajectory of the plan, in order (empty: none placed yet).
        self.plans: tuple[Plan, ...] = ()
        #: Index of the current trajectory in :attr:`plans`.
        self.current = 0
        #: Trajectory points placed before a plan exists (``entry`` / ``target``), LPS mm.
        self.draft: dict[str, np.ndarray] = {}
        #: An arch drawn before any trajectory exists ((K, 3) LPS mm); the first one takes it.
        self.draft_arch: np.ndarray | None = None
        self.path: PathView | None = None
        self.path_error = ""
        self.rehearsing = False
        #: The series' HU uncertainty (``ctdrill gui --hu-sigma``), entered into the force band.
        self.hu_uncertainty: HuUncertainty | None = None
        self.live_depth_mm: float | None = None
        self.suggestion: Suggestion | None = None
        #: Candidate of :attr:`suggestion` adopted as the plan's axis (None: none).
        self.adopted: int | None = None
        #: "" (idle), "running", or why the last search failed.
        self.suggest_status = ""
        self.history = History()
        self.debrief: object = None
        self._paths: dict[Plan, PathView] = {}  # by trajectory object (Plan compares by id)

    # ------------------------------------------------------------------ reading
    @property
    def plan(self) -> Plan | None:
        """The current trajectory (None: no trajectory placed yet)."""
        return self.plans[self.current] if self.plans else None

    @property
    def arch_lps(self) -> np.ndarray | None:
        """The dental arch ((K, 3) LPS mm, shared by every trajectory), or None."""
        plan = self.plan
        return self.draft_arch if plan is None else plan.arch_lps

    @property
    def can_undo(self) -> bool:
        """An edit can be undone."""
        return self.history.undo_name is not None

    @property
    def can_redo(self) -> bool:
        """An undone edit can be applied again."""
        return self.history.redo_name is not None

    # ------------------------------------------------------------------ series
    def set_volume(self, volume: CTVolume, path: str, surface: Any) -> bool:
        """Open a new series (refused while a rehearsal runs)."""
        if self.rehearsing:
            self.edit_refused.emit("a rehearsal runs: stop it before opening another series")
            return False
        self.volume, self.volume_path = volume, path
        self._paths.clear()
        self.path, self.path_error = None, ""  # the old series' result is not this one's
        self._drop_suggestion()
        self.set_surface(surface)
        self.volume_changed.emit(volume)
        return True

    def set_surface(self, surface: Any) -> None:
        """A new bone surface for the open series."""
        self.surface = surface
        self.surface_changed.emit(surface)

    # ------------------------------------------------------------------ plan edits
    def set_plans(
        self, plans: tuple[Plan, ...] | list[Plan], current: int = 0, *, edit: str | None = None
    ) -> bool:
        """Make ``plans`` the trajectories, ``current`` the current one.

        ``edit`` names the change as an undo step; without it the plans are a new document (a
        plan file opened): the history starts again. Refused while a rehearsal runs.
        """
        plans = tuple(plans)
        if plans and not 0 <= current < len(plans):
            raise IndexError(f"current {current} is not a trajectory of {len(plans)}")
        if not self._editable():
            return False
        before = self._state()
        self._drop_suggestion()
        self._apply(State(plans, current if plans else 0))
        if edit is None:
            self.history.clear()
        else:
            self.history.push(edit, before)
        self.history_changed.emit()
        return True

    def set_plan(
        self, plan: Plan | None, *, adopted: int | None = None, edit: str | None = None
    ) -> bool:
        """Make ``plan`` the current trajectory (refused while a rehearsal runs).

        Without trajectories ``plan`` becomes the first (taking the arch drawn so far); None
        removes every trajectory. Its landmarks and arch are the plan's, shared by every
        trajectory: changed on ``plan``, they change on all
        (:func:`~ctdrill.app.gui.planning.with_shared`). The edit is an undo step named
        ``edit`` (default: what changed, :func:`~ctdrill.app.gui.planning.edit_name`). The
        suggestion is dropped, unless ``adopted`` names the candidate of it that ``plan``
        takes its axis from (:meth:`adopt_candidate`)."""
        if not self._editable():
            return False
        before = self._state()
        name = edit or edit_name(self.plan, plan)
        if plan is None:
            plans: tuple[Plan, ...] = ()
        elif not self.plans:
            if plan.arch_lps is None and self.draft_arch is not None:
                plan = replace(plan, arch_lps=self.draft_arch)
            plans = (plan,)
        else:
            plans = with_shared(self.plans, self.current, plan)
        if adopted is None:
            self._drop_suggestion()
        self._apply(replace(self._state(), plans=plans, current=self.current if plans else 0))
        self.history.push(name, before)
        self.history_changed.emit()
        return True

    def select(self, index: int) -> bool:
        """Make trajectory ``index`` the current one (not an undo step; refused while a
        rehearsal runs: the device holds the current one)."""
        if not 0 <= index < len(self.plans):
            return False
        if index == self.current:
            return True
        if not self._editable():
            return False
        self._drop_suggestion()
        self._apply(State(self.plans, index))
        return True

    def add_plan(self, plan: Plan) -> bool:
        """Append ``plan`` as a new trajectory and make it current (an undo step); it takes
        the plan's landmarks and arch, shared by every trajectory."""
        if self.plans:
            plan = replace(plan, landmarks=self.plans[0].landmarks, arch_lps=self.plans[0].arch_lps)
        plans = (*self.plans, plan)
        return self.set_plans(plans, len(plans) - 1, edit=f"add trajectory {plan.name!r}")

    def remove_plan(self, index: int) -> bool:
        """Remove trajectory ``index`` (an undo step); the one before it becomes current."""
        if not 0 <= index < len(self.plans):
            return False
        gone = self.plans[index]
        plans = self.plans[:index] + self.plans[index + 1 :]
        if index < self.current:
            current = self.current - 1
        elif index == self.current:
            current = max(index - 1, 0)
        else:
            current = self.current
        return self.set_plans(plans, current, edit=f"remove trajectory {gone.name!r}")

    def set_arch(self, arch_lps: np.ndarray | None) -> bool:
        """Give every trajectory the dental arch ``arch_lps`` ((K, 3) LPS mm; None removes
        it): one undo step. Without trajectories the arch is kept for the first one.

        An arch the plan model refuses (fewer than 2 points, repeated points) is refused with
        ``edit_refused`` naming the problem."""
        if not self._editable():
            return False
        old = self.arch_lps
        name = "remove arch" if arch_lps is None else "draw arch" if old is None else "edit arch"
        if not self.plans:
            self.draft_arch = None if arch_lps is None else np.array(arch_lps, dtype=np.float64)
            self.plans_changed.emit(self.plans)
            self.plan_changed.emit(None)
            return True
        try:
            plans = tuple(replace(p, arch_lps=arch_lps) for p in self.plans)
        except ValueError as exc:
            self.edit_refused.emit(f"error: {exc}")
            return False
        return self.set_plans(plans, self.current, edit=name)

    def undo(self) -> bool:
        """Revert the last plan edit (refused while a rehearsal runs)."""
        return self._travel(self.history.undo)

    def redo(self) -> bool:
        """Apply the last undone plan edit again (refused while a rehearsal runs)."""
        return self._travel(self.history.redo)

    def _travel(self, step: Callable[[State], State | None]) -> bool:
        if not self._editable():
            return False
        state = step(self._state())
        if state is None:
            return False
        self._drop_suggestion()
        self._apply(state)
        self.history_changed.emit()
        return True

    def _editable(self) -> bool:
        if self.rehearsing:
            self.edit_refused.emit(LOCKED_MESSAGE)
            return False
        return True

    def _state(self) -> State:
        return State(self.plans, self.current, self.suggestion, self.adopted)

    def _apply(self, state: State) -> None:
        """Show ``state``: the plans, the current one, its cached path, its suggestion."""
        self.plans, self.current = state.plans, state.current
        if state.suggestion is not None:
            self.suggestion, self.adopted = state.suggestion, state.adopted
        self.draft = {}
        if self.plans:
            self.draft_arch = None
        plan = self.plan
        cached = None if plan is None else self._paths.get(plan)
        self.path, self.path_error = cached, ""
        self.plans_changed.emit(self.plans)
        self.plan_changed.emit(plan)
        if cached is not None:
            self.path_changed.emit(cached)
        if state.suggestion is not None:
            self.suggestion_changed.emit(state.suggestion)

    # ------------------------------------------------------------------ suggestions
    def request_suggestion(self, space: SearchSpace) -> bool:
        """Ask for a search around the plan (refused without a series and a plan, or while a
        rehearsal runs)."""
        if self.rehearsing:
            self.edit_refused.emit(LOCKED_MESSAGE)
            return False
        if self.volume is None or self.plan is None:
            self.edit_refused.emit("open a series and a plan before asking for suggestions")
            return False
        self.suggestion, self.adopted, self.suggest_status = None, None, "running"
        self.suggestion_changed.emit(None)
        self.suggestion_requested.emit(space)
        return True

    def set_suggestion(self, plan: Plan, suggestion: Suggestion) -> None:
        """The search around ``plan`` finished (dropped if the plan changed meanwhile)."""
        if plan is not self.plan or self.suggest_status != "running":
            return
        self.suggestion, self.adopted, self.suggest_status = suggestion, None, ""
        self.suggestion_changed.emit(suggestion)

    def set_suggestion_failed(self, plan: Plan, message: str) -> None:
        """The search around ``plan`` failed: ``message`` says why."""
        if plan is not self.plan or self.suggest_status != "running":
            return
        self.suggestion, self.adopted, self.suggest_status = None, None, message
        self.suggestion_changed.emit(None)

    def adopt_candidate(self, index: int) -> bool:
        """Make candidate ``index`` of the suggestion the plan's axis (everything else kept;
        an undo step)."""
        suggestion = self.suggestion
        if suggestion is None or not 0 <= index < suggestion.candidates.size:
            return False
        if not self.set_plan(
            suggestion.plan_of(index), adopted=index, edit=f"adopt suggested axis {index + 1}"
        ):
            return False
        self.adopted = index
        self.suggestion_changed.emit(suggestion)
        return True

    def _drop_suggestion(self) -> None:
        if self.suggestion is not None or self.suggest_status:
            self.suggestion, self.adopted, self.suggest_status = None, None, ""
            self.suggestion_changed.emit(None)

    def set_draft_point(self, name: str, point_lps: np.ndarray) -> None:
        """Keep ``entry`` or ``target`` placed while no plan exists (views redraw it)."""
        if not self._editable():
            return
        self.draft = {**self.draft, name: np.asarray(point_lps, dtype=np.float64).reshape(3)}
        self.plan_changed.emit(None)

    # ------------------------------------------------------------------ results
    def set_path(self, view: PathView) -> None:
        """The path result for the current plan (kept for its trajectory; not shown if
        computed for another plan)."""
        if view.plan in self.plans:
            self._paths[view.plan] = view
            while len(self._paths) > PATH_CACHE_SIZE:
                del self._paths[next(iter(self._paths))]
        if view.plan is not self.plan:
            return
        self.path, self.path_error = view, ""
        self.path_changed.emit(view)

    def cached_path(self, plan: Plan) -> PathView | None:
        """The path result already computed for ``plan`` on this series, or None."""
        return self._paths.get(plan)

    def set_path_failed(self, plan: Plan, message: str) -> None:
        """No path for ``plan``: the result is unknown (never shown as safe)."""
        if plan is not self.plan:
            return
        self.path, self.path_error = None, message
        self.path_changed.emit(None)

    def set_rehearsing(self, running: bool) -> None:
        """A rehearsal started (the plan locks) or ended (it unlocks)."""
        if running != self.rehearsing:
            self.rehearsing = running
            if not running:
                self.live_depth_mm = None
            self.rehearsal_changed.emit(running)

    def set_debrief(self, debrief: object) -> None:
        """A rehearsal ended: its debrief (the debrief page shows it)."""
        self.debrief = debrief
        self.debrief_changed.emit(debrief)

    def set_live_depth(self, depth_mm: float) -> None:
        """The drill's depth reported by the device during a rehearsal, mm."""
        self.live_depth_mm = depth_mm
        self.live_depth_changed.emit(depth_mm)
