"""Trajectory search: many candidate trajectories over one CT at once (issue 17).

:mod:`ctdrill.app.search.evaluate` evaluates a batch of trajectories with the same answers as
:func:`ctdrill.app.pipeline.plan_path`, one trajectory at a time.
"""
