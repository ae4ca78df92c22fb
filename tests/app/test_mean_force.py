"""The window's force curve is ``S0 (1 + Ke v)`` from the feed factor's owner, as ``force.csv``.

Before issue 13 the GUI (``app/gui/results.py``) and the export plot computed ``1 + Ke v``
themselves without the feed cap that ``force_n`` applies.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ctdrill.app.gui.results import path_view
from ctdrill.engine.path import plan_path
from ctdrill.engine.plans import plan_calibration
from ctdrill.imaging import load_plan, load_series
from ctdrill.model.force import MAX_FEED_MM_S
from ctdrill.model.profile import force_series_n
from ctdrill.resources import asset


def test_the_window_draws_the_mean_force_the_export_writes() -> None:
    demo = asset("demo")
    plan = replace(load_plan(demo / "plan.json"), feed_mm_s=2.0 * MAX_FEED_MM_S)
    result = plan_path(load_series(demo / "ct"), plan, plan_calibration(plan))
    view = path_view(plan, result)
    prof = result.profile
    without_vibration = force_series_n(
        prof, prof.depth_mm, plan.feed_mm_s, np.full(prof.depth_mm.shape, np.inf)
    )
    np.testing.assert_allclose(view.curves.force_n, without_vibration, rtol=1e-12)
