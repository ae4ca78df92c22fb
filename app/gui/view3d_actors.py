"""The 3D view's VTK actors, on its render thread: the bone surface's pieces, the coarser surface
a refined one replaces, and the plan's actors (:func:`ctdrill.app.gui.scene.plan_actors`, the
unchanged ones kept across rebuilds). Every method runs inside a work item of the view's
:class:`~ctdrill.app.gui.render_thread.RenderThread`."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from ctdrill.app.gui.camera import add_orientation_marker
from ctdrill.app.gui.scene import (
    BACKGROUND,
    Kept,
    SceneInput,
    add_bone,
    plan_actors,
    set_drill_depth,
)

if TYPE_CHECKING:
    import pyvista as pv


class SceneActors:
    """The view's VTK actors, touched only on the render thread (inside work items): the bone
    pieces (``bone:<surface>:<piece>``, the current surface's first also as ``bone``), the
    coarser surface a refined one replaces, and the plan's; :attr:`shown` is the name -> actor
    map the UI thread reads (a new dict on every change, never changed in place)."""

    def __init__(self) -> None:
        self.bone: dict[str, Any] = {}
        self.old_bone: dict[str, Any] = {}
        self.kept: Kept = {}
        self.plan: dict[str, Any] = {}
        self.shown: dict[str, Any] = {}

    def _publish(self) -> None:
        bone = {**self.old_bone, **self.bone}
        first = {"bone": self.bone[min(self.bone, key=_piece_no)]} if self.bone else {}
        self.shown = {**bone, **first, **self.plan}

    def setup(self, stage: Any) -> None:
        stage.set_background(BACKGROUND[0], top=BACKGROUND[1])
        add_orientation_marker(stage)

    def drop_bone(self, stage: Any) -> None:
        """Remove every bone actor (the GPU buffers go with them)."""
        for actor in [*self.old_bone.values(), *self.bone.values()]:
            stage.remove_actor(actor)
        self.bone, self.old_bone = {}, {}
        self._publish()

    def drop_old(self, stage: Any) -> None:
        for actor in self.old_bone.values():
            stage.remove_actor(actor)
        self.old_bone = {}
        self._publish()

    def keep_old(self) -> None:
        """The current surface's pieces become the old ones (a refined one follows)."""
        self.old_bone, self.bone = {**self.old_bone, **self.bone}, {}

    def add_piece(self, stage: Any, name: str, piece: pv.PolyData, *, last: bool) -> None:
        self.bone[name] = add_bone(stage, piece, name=name)
        if last:
            self.drop_old(stage)
        self._publish()

    def set_bone_visible(self, visible: bool) -> None:
        for actor in self.bone.values():
            actor.SetVisibility(visible)

    def show_plan(self, stage: Any, scene: SceneInput) -> None:
        plan = plan_actors(stage, scene, self.kept)  # the unchanged ones kept
        keep = {id(a) for a in plan.values()}
        for actor in self.plan.values():
            if id(actor) not in keep:
                stage.remove_actor(actor)
        self.plan = plan
        self._publish()

    def set_drill(self, axis_lps: np.ndarray, depth_mm: float) -> None:
        set_drill_depth(self.plan, axis_lps, depth_mm)


def _piece_no(name: str) -> int:
    return int(name.rsplit(":", 1)[1])
